"""Background: which pixels changed in a frame, and a model of the scene without its people.

:mod:`~sensor_node.background.model` (subtraction, frame differencing, abnormal change, update outside
objects), :mod:`~sensor_node.background.shadows` (cast shadows and highlights are the background),
:mod:`~sensor_node.background.still` (still regions: ghosts absorbed, people who pause kept) and
:mod:`~sensor_node.background.ghosts` (the ghost tests).
"""
