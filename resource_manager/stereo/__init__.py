"""Stereo: the paper's pair geometry. Pair ranking by the error model, the 3D blob match (Eq. 7) and its matchers,
localisation by triangulation (Eq. 1) or size ratio (Eq. 2)."""
