"""Pair choice by the error model: which two cameras should localise a person.

For a predicted person position, every pair of cameras that sees the person is
ranked by :func:`common.error_model.pair_position_error` -- the predicted RMS
position error σ√(D1²+D2²)/sin φ0, plus the baseline term when either pose
comes from mutual calibration (σ_B ≈ B²σ_α/(2R), carried by the pose). The
best pair is the paper's "subset of better sensor viewpoints".

To bound the cost with many cameras, only the ``max_cameras`` nearest cameras
that see the person are paired (their bearing error turns into the smallest
position error).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from common.arrays import FloatArray, IntArray, pairs_of
from common.error_model import pair_error_f, pair_position_errors

__all__ = ["CameraGeom", "PairCandidate", "rank_pairs", "rank_pairs_many"]

PAIR_CAMERAS = 2
"""Cameras in a stereo pair: with fewer seeing a person, no pair localises them."""


@dataclass(frozen=True, slots=True)
class CameraGeom:
    """What the error model needs to know about one camera."""

    sensor_id: str
    origin_xy: FloatArray
    sigma_rad: float
    sigma_xy_m: float = 0.0
    """Position uncertainty of the pose (0: surveyed)."""


@dataclass(frozen=True, slots=True)
class PairCandidate:
    a: str
    b: str
    error_m: float
    """Predicted RMS position error of localising the target with this pair."""


def rank_pairs(target_xy: FloatArray, cameras: list[CameraGeom], max_cameras: int = 5) -> list[PairCandidate]:
    """Every pair among the cameras that see the target, best (smallest predicted error) first."""
    if len(cameras) < PAIR_CAMERAS:
        return []
    tx, ty = float(target_xy[0]), float(target_xy[1])
    # Plain floats: at most max_cameras (5) cameras, 10 pairs; numpy per pair (or per 10-element array) costs more.
    geo = [(c, float(c.origin_xy[0]), float(c.origin_xy[1])) for c in cameras]
    if len(geo) > max_cameras:
        geo = sorted(geo, key=lambda g: math.hypot(g[1] - tx, g[2] - ty))[:max_cameras]
    out: list[PairCandidate] = []
    for (ca, xa, ya), (cb, xb, yb) in itertools.combinations(geo, 2):
        sigma = math.hypot(ca.sigma_rad, cb.sigma_rad) / math.sqrt(2.0)
        sigma_b = math.hypot(ca.sigma_xy_m, cb.sigma_xy_m)
        err = pair_error_f(xa, ya, xb, yb, tx, ty, sigma, sigma_b)
        if not math.isfinite(err):
            err = math.inf
        out.append(PairCandidate(ca.sensor_id, cb.sensor_id, err))
    out.sort(key=lambda p: p.error_m)
    return out


def rank_pairs_many(
    target_xy: FloatArray,
    origin: FloatArray,
    sigma_rad: FloatArray,
    sigma_xy_m: FloatArray,
    *,
    count: IntArray,
    max_cameras: int = 5,
) -> tuple[IntArray, IntArray, FloatArray, IntArray]:
    """:func:`rank_pairs` of many targets at once, each with its own cameras (a tick's people: one pass).

    Args:
        target_xy: (k, 2) the targets.
        origin: (k, w, 2) the cameras of each target, in its first ``count`` slots.
        sigma_rad: (k, w) their bearing errors.
        sigma_xy_m: (k, w) their position errors.
        count: (k,) how many cameras each target has.
        max_cameras: only this many cameras nearest each target are paired.

    Returns:
        (a, b, error_m) (k, q): each target's pairs best first, as the slots of their two cameras and their
        predicted errors (slots as :func:`rank_pairs` orders them: ties in the order it makes the pairs), and (k,)
        how many of them each target has (the rest of its row is padding).
    """
    k, w = sigma_rad.shape
    used = np.arange(w) < count[:, None]
    m = min(w, max_cameras)
    if m < PAIR_CAMERAS:
        return np.zeros((k, 0), np.int64), np.zeros((k, 0), np.int64), np.zeros((k, 0)), np.zeros(k, np.int64)
    # The nearest max_cameras cameras (in order of distance) where there are more; else all, in their order.
    dist = np.where(
        used, np.hypot(origin[:, :, 0] - target_xy[:, 0, None], origin[:, :, 1] - target_xy[:, 1, None]), np.inf
    )
    nearest = np.argsort(dist, axis=1, kind="stable")[:, :m]
    chosen = np.where((count > max_cameras)[:, None], nearest, np.arange(m))
    ia, ib = pairs_of(m)
    sa, sb = chosen[:, ia], chosen[:, ib]
    valid = ib[None, :] < np.minimum(count, m)[:, None]
    rows = np.arange(k)[:, None]
    sigma = np.hypot(sigma_rad[rows, sa], sigma_rad[rows, sb]) / math.sqrt(2.0)
    sigma_b = np.hypot(sigma_xy_m[rows, sa], sigma_xy_m[rows, sb])
    target = np.broadcast_to(target_xy[:, None, :], (*sa.shape, 2))
    err = pair_position_errors(
        origin[rows, sa].reshape(-1, 2),
        origin[rows, sb].reshape(-1, 2),
        target.reshape(-1, 2),
        sigma.ravel(),
        sigma_b.ravel(),
    ).reshape(sa.shape)
    err = np.where(np.isfinite(err), err, np.inf)
    order = np.lexsort((err, ~valid), axis=1)  # the pairs there, by error; ties in their order
    return (
        np.take_along_axis(sa, order, axis=1),
        np.take_along_axis(sb, order, axis=1),
        np.take_along_axis(err, order, axis=1),
        valid.sum(axis=1),
    )
