"""Track: the state of every followed person, the motion model and filter, assignment, births and the life cycle.

The only package that changes a track's state (:mod:`resource_manager.track.tracker`).
"""
