"""Per-view tables for the vectorised Eq. (7) of many camera pairs (:func:`~resource_manager.match.match_matrices`).

Every view used by a batch of pairs is padded to a common blob count once; pairs gather their rows by index.
The colour factor r_is (Bhattacharyya coefficients of the histograms) is computed here for all pairs at once.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from common.arrays import FloatArray
from common.histograms import bhattacharyya_coefficients, histogram_root
from resource_manager.views.blobs import ViewBlobs

__all__ = ["Tables", "colour_table"]

LOOP_MAX_PAIRS = 2
"""Up to this many pairs, r_is is a loop over the pairs (cheaper than building the stacked table)."""


class Tables:
    """Per-blob quantities of every view used by a batch of pairs, padded to a common blob count.

    Several pairs share a view (16 cameras, 20 people: ~12 pairs over ~14 views), so each view is padded and
    its per-blob trigonometry (tan of half widths, tops, bottoms) computed once; pairs gather rows by index.
    """

    def __init__(self, views: list[ViewBlobs], n: int) -> None:
        counts = np.array([v.n for v in views], dtype=np.int64)
        total = int(counts.sum())
        # Flat positions of every blob in the (v, n) padded tables.
        starts = np.repeat(np.arange(len(views), dtype=np.int64) * n - np.cumsum(counts) + counts, counts)
        self.flat = np.arange(total, dtype=np.int64) + starts
        self.shape = (len(views), n)
        self.views = views
        self.total = total

    def table(self, columns: list[list[FloatArray]]) -> FloatArray:
        """(v, n, c) per-blob values of c columns (one list of per-view arrays each), NaN where padded."""
        out = np.full((self.shape[0] * self.shape[1], len(columns)), np.nan)
        if self.total:
            out[self.flat] = np.column_stack([np.concatenate(col) for col in columns])
        return out.reshape(self.shape[0], self.shape[1], len(columns))

    def flags(self, arrays: list[npt.NDArray[np.bool_] | None]) -> npt.NDArray[np.bool_]:
        """(v, n) flags, False where an array is None or padded."""
        out = np.zeros(self.shape[0] * self.shape[1], dtype=bool)
        if self.total and any(a is not None for a in arrays):
            out[self.flat] = np.concatenate(
                [
                    a[: v.n] if a is not None else np.zeros(v.n, dtype=bool)
                    for a, v in zip(arrays, self.views, strict=True)
                ]
            )
        return out.reshape(self.shape)


def colour_table(
    pairs: list[tuple[ViewBlobs, ViewBlobs]],
    use_colour: bool,
    shape: tuple[int, int, int],
    *,
    tabs: Tables,
    ia: npt.NDArray[np.int64],
    ib: npt.NDArray[np.int64],
) -> FloatArray:
    """r_is (p, na, nb): the Bhattacharyya coefficients of the histograms (1 where a view has none)."""
    if not use_colour:
        return np.ones(shape)
    roots = [
        None if v.hist is None else (v.hist_sqrt if v.hist_sqrt is not None else histogram_root(v.hist))
        for v in tabs.views
    ]
    bins = {r.shape[1] for r in roots if r is not None}
    _, na, nb = shape
    if (
        len(pairs) > LOOP_MAX_PAIRS
        and len(bins) == 1
        and all(r is not None or v.n == 0 for r, v in zip(roots, tabs.views, strict=True))
    ):
        # Every view sends histograms of the same size: one stacked product for all pairs (a few pairs: the
        # loop below is cheaper than building the table).
        k = next(iter(bins))
        flat = np.zeros((tabs.shape[0] * tabs.shape[1], k))
        if tabs.total:
            flat[tabs.flat] = np.concatenate([r for r in roots if r is not None])
        table = flat.reshape(tabs.shape[0], tabs.shape[1], k)
        return bhattacharyya_coefficients(table[ia, :na], table[ib, :nb])
    out = np.ones(shape)
    for k, (a, b) in enumerate(pairs):
        if a.hist is not None and b.hist is not None and a.hist.shape[1] == b.hist.shape[1]:
            sa = a.hist_sqrt if a.hist_sqrt is not None else histogram_root(a.hist)
            sb = b.hist_sqrt if b.hist_sqrt is not None else histogram_root(b.hist)
            out[k, : a.n, : b.n] = bhattacharyya_coefficients(sa, sb)
    return out
