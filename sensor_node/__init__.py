"""Sensor node: one process per camera, from frames to published blob features.

Pure stages (no zenoh), one module or package each: :mod:`~sensor_node.unwarp` (annular ->
panorama), :mod:`~sensor_node.background` (the model: subtraction, frame differencing,
abnormal change, update outside objects; shadows, still regions, ghosts),
:mod:`~sensor_node.segmentation` (blobs, split at head valleys and between the 2D tracks'
predicted heads), :mod:`~sensor_node.head`, :mod:`~sensor_node.features` (I, theta, w, h),
:mod:`~sensor_node.tracks2d`, :mod:`~sensor_node.sightings` (Eq. 3) and
:mod:`~sensor_node.detections` (MOT files -> Features), composed by
:mod:`~sensor_node.pipeline`. Frame sources: :mod:`~sensor_node.sources`
(OpenCV, folders), :mod:`~sim.source` (the simulated camera);
PTZ heads: :mod:`~sensor_node.ptz`. :mod:`~sensor_node.build` wires a config
into parts; the shell :mod:`~sensor_node.node` captures, runs them and
publishes; :mod:`~sensor_node.cli` is the entry point.
"""
