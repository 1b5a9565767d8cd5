"""Colour looks: how much blobs and tracks look alike (the colour term of identity, beside Eq. 7's r_is).

A track keeps, per camera, a running mean of the square-rooted, L1-normalised colour histograms of the blobs
that localised it (:func:`learn_look`): the same shirt looks different from another side or under another light.
Every comparison of colours here is one Bhattacharyya coefficient ``BC(p, q) = Σ √p·√q`` of square-rooted
histograms, computed by :func:`bhattacharyya` in whatever shape it is asked: blobs of a view against the tracks'
looks there (the support assignment), the blobs of a fix against one track (is the fix in its colours?), and
two tracks against each other over the views both have (are they one person?).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

if TYPE_CHECKING:
    from resource_manager.track.state import TrackRecord
    from resource_manager.views.blobs import ViewBlobs

__all__ = ["bhattacharyya", "learn_look", "learn_looks", "mean_similarity"]

FloatArray = npt.NDArray[np.float64]


def bhattacharyya(hist_sqrt: FloatArray, looks: Sequence[FloatArray | None]) -> FloatArray:
    """(n, m) Bhattacharyya coefficients of n square-rooted histograms against m looks, in [0, 1].

    Args:
        hist_sqrt: (n, k) square-rooted histograms (or one, shape (k,)).
        looks: m square-rooted histograms; None or another length than k: no comparison (NaN column).
    """
    h = np.atleast_2d(np.asarray(hist_sqrt, dtype=np.float64))
    out = np.full((h.shape[0], len(looks)), np.nan)
    cols = [c for c, look in enumerate(looks) if look is not None and look.shape == (h.shape[1],)]
    if cols and h.shape[0]:
        stacked = np.array([looks[c] for c in cols])
        out[:, cols] = np.minimum(np.maximum(h @ stacked.T, 0.0), 1.0)
    return out


def mean_similarity(pairs: Iterable[tuple[FloatArray | None, FloatArray | None]]) -> float | None:
    """Mean Bhattacharyya coefficient over (histogram, look) pairs that can be compared; None if none can."""
    sims = [
        float(bhattacharyya(h, [look])[0, 0])
        for h, look in pairs
        if h is not None and look is not None and h.shape == look.shape
    ]
    return sum(sims) / len(sims) if sims else None


def learn_look(tr: TrackRecord, used_blobs: dict[str, int], views: dict[str, ViewBlobs], alpha: float) -> None:
    """Fold the colours of the blobs assigned to ``tr`` into its per-view looks (running mean of weight
    ``alpha``, renormalised)."""
    learn_looks([(tr, used_blobs, alpha)], views)


def learn_looks(learnt: Sequence[tuple[TrackRecord, dict[str, int], float]], views: dict[str, ViewBlobs]) -> None:
    """:func:`learn_look` of many tracks at once: (track, sensor id -> blob, alpha) each."""
    hists = {sid: v.hist_sqrt for sid, v in views.items() if v.hist_sqrt is not None}
    # (track, sensor id, its look there, the blob's histogram, alpha) of every blob assigned.
    seen = [
        (tr, sid, tr.looks.get(sid), hists[sid][i], alpha)
        for tr, used_blobs, alpha in learnt
        for sid, i in used_blobs.items()
        if sid in hists
    ]
    mixed: dict[int, list[tuple[TrackRecord, str, FloatArray, FloatArray, float]]] = {}
    for tr, sid, old, h, alpha in seen:
        if old is None or old.shape != h.shape:
            tr.looks[sid] = h.copy()
        else:
            mixed.setdefault(h.shape[0], []).append((tr, sid, old, h, alpha))
    for rows in mixed.values():
        weight = np.array([r[4] for r in rows])[:, None]
        mix = (1.0 - weight) * np.array([r[2] for r in rows]) + weight * np.array([r[3] for r in rows])
        mix = mix / np.maximum(np.linalg.norm(mix, axis=1), 1e-12)[:, None]
        for (tr, sid, *_), look in zip(rows, mix, strict=True):
            tr.looks[sid] = look
