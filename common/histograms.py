"""The one histogram distance: the Bhattacharyya coefficient of colour histograms, defined once.

The manager compares blobs' colours in two places -- the colour factor r_is of Eq. (7) between two views'
blobs (``resource_manager/stereo/match_tables.py``) and a track's looks against blobs and other tracks
(``resource_manager/track/looks.py``) -- with the same coefficient ``BC(p, q) = Σ √p·√q`` of L1-normalised
histograms p and q: 1 for the same colours, 0 for colours that share no bin.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from common.arrays import FloatArray

__all__ = ["bhattacharyya_coefficients", "histogram_root"]


def histogram_root(hist: npt.ArrayLike) -> FloatArray:
    """The element-wise square root of histograms, negative bins (a codec's rounding) taken as 0."""
    return np.sqrt(np.clip(hist, 0.0, None))


def bhattacharyya_coefficients(p_root: npt.ArrayLike, q_root: npt.ArrayLike) -> FloatArray:
    """Bhattacharyya coefficients of square-rooted histograms (:func:`histogram_root`): every row of ``p_root``
    against every row of ``q_root``, in [0, 1] (rounding can leave a sum of products a little outside).

    Args:
        p_root: (..., n, k) square-rooted histograms.
        q_root: (..., m, k) square-rooted histograms; leading axes broadcast as in ``np.matmul``.

    Returns:
        (..., n, m) coefficients.
    """
    products = np.matmul(p_root, np.swapaxes(q_root, -1, -2))
    return np.minimum(np.maximum(products, 0.0), 1.0)  # np.clip, without its per-call overhead
