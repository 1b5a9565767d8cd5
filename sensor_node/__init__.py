"""Sensor node: one process per camera, from frames to published blob features.

Pure stages (no zenoh): :mod:`~sensor_node.unwarp`, :mod:`~sensor_node.background`,
:mod:`~sensor_node.blobs`, :mod:`~sensor_node.head`, :mod:`~sensor_node.features`,
:mod:`~sensor_node.tracks2d`, :mod:`~sensor_node.sightings`, :mod:`~sensor_node.detections`;
the shell :mod:`~sensor_node.node` captures, runs them and publishes.
"""
