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
from typing import TYPE_CHECKING, Literal

import numpy as np
import numpy.typing as npt

from common.error_model import pair_error_f

if TYPE_CHECKING:
    from resource_manager.match import ViewBlobs
    from resource_manager.track import TrackRecord

__all__ = ["RERANK_MOVE_M", "CameraGeom", "PairCandidate", "rank_for_track", "rank_pairs"]

FloatArray = npt.NDArray[np.float64]
RERANK_MOVE_M = 0.5
"""A track's camera pairs are re-ranked by the error model when it moved this far (or its views changed)."""


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


def rank_for_track(
    tr: TrackRecord,
    *,
    sup: dict[str, int],
    views: dict[str, ViewBlobs],
    pose_sigma: dict[str, float],
    max_cams: int,
    chosen: set[tuple[str, str]],
    choice: Literal["error_model", "random"] = "error_model",
    reuse_tolerance: float = 1.0,
    rng: np.random.Generator | None = None,
) -> list[PairCandidate]:
    """A track's camera pairs (cameras ``sup`` that support it), best first by the error model.

    The ranking is kept on the track (``pair_cache``) until it moved :data:`RERANK_MOVE_M` or a camera was added.
    ``chosen``: pairs already matched this tick; one nearly as good (``reuse_tolerance``) goes first, saving a
    whole Eq. 7 matrix. ``choice = "random"``: the pairs shuffled (a baseline to compare the error model with).
    """
    key = frozenset(sup)
    pc = tr.pair_cache
    ranked: list[PairCandidate] = []
    if pc is not None and key <= pc[2] and math.hypot(tr.x[0] - pc[0], tr.x[1] - pc[1]) < RERANK_MOVE_M:
        # Same place, no new camera: the earlier ranking restricted to the cameras that see it now.
        ranked = [c for c in pc[3] if c.a in key and c.b in key]
    if not ranked:
        cams = [CameraGeom(s, views[s].origin_xy, views[s].sigma_rad, pose_sigma.get(s, 0.0)) for s in sup]
        ranked = rank_pairs(tr.x[:2].copy(), cams, len(cams) if choice == "random" else max_cams)
        tr.pair_cache = (float(tr.x[0]), float(tr.x[1]), key, list(ranked))
    if choice == "random":
        order = (rng if rng is not None else np.random.default_rng()).permutation(len(ranked))
        return [ranked[int(i)] for i in order]
    if reuse_tolerance > 1.0 and ranked and tuple(sorted((ranked[0].a, ranked[0].b))) not in chosen:
        reuse = next(
            (
                c
                for c in ranked[1:]
                if c.error_m <= reuse_tolerance * ranked[0].error_m and tuple(sorted((c.a, c.b))) in chosen
            ),
            None,
        )
        if reuse is not None:
            ranked = [reuse, *[c for c in ranked if c is not reuse]]
    return ranked
