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
import numpy.typing as npt

from common.error_model import pair_error_f

__all__ = ["CameraGeom", "PairCandidate", "rank_pairs"]

FloatArray = npt.NDArray[np.float64]


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
    if len(cameras) < 2:
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
