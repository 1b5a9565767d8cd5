"""The resource manager tier: fuses every sensor's features into 3D tracks (the paper's middle tier).

``fusion.Fusion`` is the whole per-tick computation, pure; ``node`` is the zenoh shell; ``cli`` the entry point.
"""
