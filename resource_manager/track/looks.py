"""Colour looks: how much blobs and tracks look alike (the colour term of identity, beside Eq. 7's r_is).

A track keeps, per camera, a running mean of the square-rooted, L1-normalised colour histograms of the blobs
that localised it (:func:`learn_looks`): the same shirt looks different from another side or under another light.
Every comparison of colours here is one Bhattacharyya coefficient ``BC(p, q) = Σ √p·√q`` of square-rooted
histograms, computed by :func:`bhattacharyya` in whatever shape it is asked: blobs of a view against the tracks'
looks there (:mod:`.observe`), and two tracks against each other over the views both have (is a new track a
lost one back? :mod:`.life`). A coefficient becomes evidence by :func:`colour_ln_lr`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np

from common.arrays import FloatArray
from common.histograms import bhattacharyya_coefficients

if TYPE_CHECKING:
    from resource_manager.track.state import TrackRecord
    from resource_manager.views.blobs import Views

__all__ = ["bhattacharyya", "colour_ln_lr", "learn_looks", "looks_ln_odds"]


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
        out[:, cols] = bhattacharyya_coefficients(h, stacked)
    return out


def colour_ln_lr(coefficient: FloatArray, sigma: float, outlier_prob: float) -> FloatArray:
    """ln of the half-normal density of the Bhattacharyya distance ``1 - BC`` (spread ``sigma``) of one person's
    colours, with an outlier floor, against a uniform distance for anyone else, at coefficients ``coefficient``."""
    dist = 1.0 - np.clip(coefficient, 0.0, 1.0)
    same = 2.0 / (sigma * math.sqrt(2.0 * math.pi)) * np.exp(-0.5 * (dist / sigma) ** 2)
    return np.asarray(np.log((1.0 - outlier_prob) * same + outlier_prob), dtype=np.float64)


def looks_ln_odds(
    a: Mapping[str, FloatArray],
    a_s: Mapping[str, float],
    b: Mapping[str, FloatArray],
    b_s: Mapping[str, float],
    *,
    sigma: float,
    outlier_prob: float,
    min_s: float,
) -> float | None:
    """ln p(colours | one person) / p(colours | two people) of two tracks' looks, summed over the views where both
    have one learnt for at least ``min_s`` (None where there is none: colour cannot tell)."""
    views = [sid for sid in a if sid in b and a_s.get(sid, 0.0) >= min_s and b_s.get(sid, 0.0) >= min_s]
    pairs = [(a[sid], b[sid]) for sid in views if a[sid].shape == b[sid].shape]
    if not pairs:
        return None
    bc = np.array([float(bhattacharyya(x, [y])[0, 0]) for x, y in pairs])
    return float(np.sum(colour_ln_lr(bc, sigma, outlier_prob)))


def learn_looks(learnt: Sequence[tuple[TrackRecord, dict[str, int], float]], views: Views) -> None:
    """Fold the colours of the blobs assigned to each track into its per-view looks (running mean of weight
    alpha, renormalised): ``learnt`` holds (track, sensor id -> blob index in its view, alpha), the blobs those of
    the tick's ``views``; all tracks at once."""
    bins = views.hist_bins.tolist()
    offsets = views.offsets.tolist()
    # (track, sensor id, its view's row, the blob's entry in the views, alpha) of every blob assigned.
    seen = [(tr, sid, views.rows[sid], j, alpha) for tr, used_blobs, alpha in learnt for sid, j in used_blobs.items()]
    for size, hist in views.hist_sqrt.items():
        group = [(tr, sid, row, offsets[row] + j, alpha) for tr, sid, row, j, alpha in seen if bins[row] == size]
        if not group:
            continue
        h = hist[[e[3] for e in group]]
        olds = [tr.looks.get(sid) for tr, sid, *_ in group]
        mixed = [k for k, old in enumerate(olds) if old is not None and old.shape == (size,)]
        for k, ((tr, sid, *_), old) in enumerate(zip(group, olds, strict=True)):
            if old is None or old.shape != (size,):
                tr.looks[sid] = h[k]
        if not mixed:
            continue
        weight = np.array([group[k][4] for k in mixed])[:, None]
        mix = (1.0 - weight) * np.array([olds[k] for k in mixed]) + weight * h[mixed]
        mix = mix / np.maximum(np.linalg.norm(mix, axis=1), 1e-12)[:, None]
        for k, look in zip(mixed, mix, strict=True):
            tr, sid, *_ = group[k]
            tr.looks[sid] = look
