"""Segmentation: the changed pixels cut into one blob per person.

:mod:`~sensor_node.segmentation.blobs` (connected and nearby regions grouped into blobs and checked),
:mod:`~sensor_node.segmentation.head_splits` (a blob split at the valleys between its heads) and
:mod:`~sensor_node.segmentation.groups` (a blob split between the heads the 2D tracks predict: people
walking in a tight group).
"""
