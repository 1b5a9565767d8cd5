"""Per-view tables for the vectorised Eq. (7) of many camera pairs (:func:`~resource_manager.match.match_matrices`).

Every view used by a batch of pairs is padded to a common blob count once (its blobs gathered from the tick's
:class:`~resource_manager.views.blobs.Views` by index); pairs gather their rows by index. The colour factor r_is
(Bhattacharyya coefficients of the histograms) is computed here for all pairs at once.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from common.arrays import BoolArray, FloatArray, IntArray
from common.histograms import bhattacharyya_coefficients
from resource_manager.views.blobs import Views

__all__ = ["Tables", "colour_table"]

LOOP_MAX_PAIRS = 2
"""Up to this many pairs, r_is is a loop over the pairs (cheaper than building the stacked table)."""


class Tables:
    """Per-blob quantities of every view used by a batch of pairs, padded to a common blob count.

    Several pairs share a view (16 cameras, 20 people: ~12 pairs over ~14 views), so each view is padded and
    its per-blob trigonometry (tan of half widths, tops, bottoms) computed once; pairs gather rows by index.

    Args:
        views: the tick's views.
        rows: the views used (view rows), each once.
        blobs: each one's blobs (entries of ``views``) that are matched.
        n: the common blob count (at least the largest of ``blobs``).
    """

    def __init__(self, views: Views, rows: Sequence[int], blobs: Sequence[IntArray], n: int) -> None:
        counts = np.array([len(b) for b in blobs], dtype=np.int64)
        total = int(counts.sum())
        # Flat positions of every blob in the (v, n) padded tables.
        starts = np.repeat(np.arange(len(blobs), dtype=np.int64) * n - np.cumsum(counts) + counts, counts)
        self.flat = np.arange(total, dtype=np.int64) + starts
        self.shape = (len(blobs), n)
        self.views = views
        self.rows = list(rows)
        self.blobs = list(blobs)
        self.entries = np.concatenate(self.blobs) if self.blobs else np.zeros(0, dtype=np.int64)
        self.total = total

    def table(self, columns: list[FloatArray]) -> FloatArray:
        """(v, n, c) per-blob values of c per-blob columns of the views (each (m,)), NaN where padded."""
        out = np.full((self.shape[0] * self.shape[1], len(columns)), np.nan)
        if self.total:
            out[self.flat] = np.column_stack([col[self.entries] for col in columns])
        return out.reshape(self.shape[0], self.shape[1], len(columns))

    def flags(self, values: BoolArray) -> npt.NDArray[np.bool_]:
        """(v, n) per-blob flags of the views (``values``: (m,)), False where padded."""
        out = np.zeros(self.shape[0] * self.shape[1], dtype=bool)
        if self.total:
            out[self.flat] = values[self.entries]
        return out.reshape(self.shape)

    def roots(self) -> list[FloatArray | None]:
        """Each view's square-rooted histograms of its blobs (None: it sends none)."""
        bins = self.views.hist_bins[self.rows].tolist()
        return [self.views.hist_sqrt[k][b] if k else None for k, b in zip(bins, self.blobs, strict=True)]


def colour_table(
    use_colour: bool,
    shape: tuple[int, int, int],
    *,
    tabs: Tables,
    ia: npt.NDArray[np.int64],
    ib: npt.NDArray[np.int64],
) -> FloatArray:
    """r_is (p, na, nb) of the pairs of views ``ia``, ``ib`` of ``tabs``: the Bhattacharyya coefficients of the
    histograms (1 where a view has none)."""
    if not use_colour:
        return np.ones(shape)
    roots = tabs.roots()
    bins = {r.shape[1] for r in roots if r is not None}
    p, na, nb = shape
    if (
        p > LOOP_MAX_PAIRS
        and len(bins) == 1
        and all(r is not None or len(b) == 0 for r, b in zip(roots, tabs.blobs, strict=True))
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
    for k, (a, b) in enumerate(zip(ia.tolist(), ib.tolist(), strict=True)):
        sa, sb = roots[a], roots[b]
        if sa is not None and sb is not None and sa.shape[1] == sb.shape[1]:
            out[k, : len(sa), : len(sb)] = bhattacharyya_coefficients(sa, sb)
    return out
