"""The view planner's checks (paper, "Error Characteristics and View Planning"; :mod:`resource_manager.plan.planner`):
Fig. 4's predicted error of a candidate place, where a mobile camera may be sent, and whether it is worth it.

* **Mutual visibility** (Eq. 3 needs the other body in view): seen from a camera
  at height z_c whose panorama reaches down to ε_min (-15° for the PAL lens),
  the marking band of a body at horizontal range D is at elevation
  atan((z_band - z_c)/(D - R)); it stays in view (with ``elev_margin_rad``) for
  D >= R + (z_c - z_band)/tan(-ε_min - margin): a minimum baseline to every
  other panoramic body, both ways. A maximum baseline keeps the body at least
  ``min_band_px`` wide in the ranging camera: 2·asin(R/B) >= min_band_px·2π/W.
  The drive there keeps the minimum baseline to the main camera too.
* **The person in view**: the top of the head (track height) under the upper
  elevation limit ε_max: D2 >= (h - z_c)/tan(ε_max - margin); and D2 >= D1/2
  as in :func:`common.error_model.optimal_configuration` (M1 alone rewards
  parking on the target).
* **Room and clearance**: inside the room with ``margin_m``; the straight drive
  keeps ``keep_m`` from every person and clear of every other body; the person
  does not stand in the line of sight between the goal and the main camera.
* **Cost of moving** (:func:`move_payoff`): found person-seconds gained against those lost on the way.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from common.arrays import BoolArray, FloatArray
from common.error_model import normalised_error_xy, pair_position_error
from resource_manager.stereo.pairs import PAIR_CAMERAS

if TYPE_CHECKING:
    from resource_manager.plan.scene import PlanCamera, PlannerParams, Scene

__all__ = [
    "feasible",
    "found",
    "max_baseline",
    "min_baseline",
    "move_payoff",
    "others_error",
    "predicted_error",
    "segment_dist",
]


def predicted_error(xy: FloatArray, sc: Scene) -> FloatArray:
    """Predicted ∂D1 (m) for the mobile camera at each of ``xy``: Fig. 4's map in the world (model M1)."""
    main, tgt, cam = sc.main, sc.tgt, sc.cam
    v = tgt.xy - main.xy
    d1 = float(np.hypot(*v))
    c, s = v / d1
    rel = xy - main.xy
    lx = rel[:, 0] * c + rel[:, 1] * s
    ly = -rel[:, 0] * s + rel[:, 1] * c
    e = np.asarray(normalised_error_xy(lx, ly, d1, cam.radius_m), dtype=np.float64)
    return e * d1 * cam.sigma_rad


def others_error(sc: Scene) -> float:
    """The target's predicted error (m) with the best pair of the other cameras (where they will stay), without
    the mobile camera of ``sc``: what the system already has for that person (inf: no other pair)."""
    best = math.inf
    cams = sc.fixed
    for i, a in enumerate(cams):
        for b in cams[i + 1 :]:
            best = min(best, pair_position_error(a.xy, b.xy, sc.tgt.xy, max(a.sigma_rad, b.sigma_rad)))
    return best


def found(err_m: float, found_m: float) -> float:
    """Probability that a fix of predicted (RMS) error ``err_m`` lands within ``found_m`` of the person
    (Rayleigh: 1 - exp(-found_m² / err_m²))."""
    if err_m <= 0:
        return 1.0
    return 1.0 - math.exp(-((found_m / err_m) ** 2))


def move_payoff(
    sc: Scene, p: PlannerParams, goal_xy: FloatArray, goal_err: float, found_here: float, *, others_err: float
) -> tuple[float, float, float]:
    """(found person-seconds gained, lost, seconds blind) if the mobile camera of ``sc`` drives to ``goal_xy``.

    While the robot drives and settles (``blind_s = drive / speed_mps + settle_cost_s``) its views count
    for nothing (:mod:`resource_manager.views.settling`): each person it helps localise who has no other pair
    then (fewer than two other cameras) is lost, who is found now with probability :func:`found` of their
    predicted error (the target: ``found_here``). Then, for ``horizon_s``, the target is found with the
    goal's predicted error (Fig. 4's map, model M1) instead -- or the other cameras' best pair's
    (``others_err``, :func:`others_error`), if better.
    """
    cam = sc.cam
    blind_s = float(np.hypot(*(goal_xy - cam.xy))) / max(p.speed_mps, 1e-3) + p.settle_cost_s
    gain = p.horizon_s * (found(min(goal_err, others_err), p.found_m) - found_here)
    cost = 0.0
    if len(sc.fixed) < PAIR_CAMERAS:
        cost = blind_s * sum(
            found_here if t.track_id == sc.tgt.track_id else found(t.predicted_error_m, p.found_m)
            for t in sc.people
            if cam.sensor_id in t.sensors
        )
    return gain, cost, blind_s


def feasible(
    xy: FloatArray, sc: Scene, p: PlannerParams, *, drive: bool = True, transient: bool = True, bands: bool = True
) -> BoolArray:
    """Which of ``xy`` the mobile camera of ``sc`` may be sent to.

    ``drive``: also check the way there. ``transient``: also the constraints that depend on where the
    people are now (a goal already held, or where the robot stands, is not left because someone walks by).
    ``bands``: also mutual visibility (minimum and maximum baselines; not for where a robot stands whose pose
    mutual calibration knows: the bands that range it are in view there).
    """
    cam, main, tgt = sc.cam, sc.main, sc.tgt
    ok = np.ones(len(xy), dtype=bool)
    if p.room is not None:
        x0, y0, x1, y1 = p.room
        m = p.margin_m - 1e-6
        ok &= (xy[:, 0] >= x0 + m) & (xy[:, 0] <= x1 - m) & (xy[:, 1] >= y0 + m) & (xy[:, 1] <= y1 - m)
    if transient:
        # The person: head top in view, and D2 >= D1 / 2 (the interior optimum of Fig. 4).
        d1 = float(np.hypot(*(tgt.xy - main.xy)))
        d2 = np.hypot(*(xy - tgt.xy).T)
        ok &= d2 >= max(head_min_range(cam, tgt.height_m, p.elev_margin_rad), 0.5 * d1, p.keep_m)
        for person in sc.people:
            ok &= np.hypot(*(xy - person.xy).T) >= p.keep_m
            if drive:
                now = float(np.hypot(*(cam.xy - person.xy))) - 1e-6
                ok &= segment_dist(cam.xy, xy, person.xy) >= min(p.keep_m, now)
        # The line of sight to the main camera's body (mutual calibration) not blocked by the person.
        if main.radius_m > 0:
            ok &= segment_dist(main.xy, xy, tgt.xy) >= p.sight_clearance_m
    ranged = np.zeros(len(xy), dtype=bool)
    for other in sc.others if transient else sc.fixed:
        d = np.hypot(*(xy - other.xy).T)
        clear = cam.radius_m + max(other.radius_m, 0.1) + p.body_clearance_m
        lo = max(clear, min_baseline(cam, other, p)) if bands else clear
        ok &= d >= lo
        if drive:
            # The way there: clear of every body, and no nearer to the main camera's than the goal's
            # minimum baseline (its sightings range the robot all along), unless it starts nearer.
            now = float(np.hypot(*(cam.xy - other.xy))) - 1e-6
            ok &= segment_dist(cam.xy, xy, other.xy) >= min(lo if other is main else clear, now)
        if other.radius_m > 0 and cam.width_px > 0:
            ranged |= d <= max_baseline(cam, other, p)
        if bands and other is main and main.radius_m > 0:
            ok &= d <= max_baseline(cam, other, p)
    if bands and any(o.radius_m > 0 for o in sc.fixed):
        ok &= ranged
    return ok


def head_min_range(cam: PlanCamera, head_m: float, margin_rad: float) -> float:
    """Nearest horizontal range at which the top of a head ``head_m`` high is under the upper elevation limit."""
    up = cam.elev_max_rad - margin_rad
    if head_m <= cam.z_m or up <= 0:
        return 0.0
    return (head_m - cam.z_m) / math.tan(up)


def band_range(seer: PlanCamera, body: PlanCamera, p: PlannerParams) -> float:
    """Nearest range (axis to axis) at which ``seer`` sees ``body``'s band above its lower elevation limit."""
    if seer.width_px <= 0 or body.radius_m <= 0:
        return 0.0
    drop = seer.z_m - p.band_z_m
    down = -(seer.elev_min_rad + p.elev_margin_rad)
    if drop <= 0 or down <= 0:
        return 0.0
    return body.radius_m + drop / math.tan(down)


def min_baseline(cam: PlanCamera, other: PlanCamera, p: PlannerParams) -> float:
    """Mutual visibility: each body's band within the other's elevation range (both ways)."""
    return max(band_range(cam, other, p), band_range(other, cam, p))


def max_baseline(cam: PlanCamera, other: PlanCamera, p: PlannerParams) -> float:
    """Farthest range at which each body is ``min_band_px`` wide in the other's panorama (Eq. 3's α)."""
    out = math.inf
    for seer, body in ((cam, other), (other, cam)):
        if seer.width_px <= 0 or body.radius_m <= 0:
            continue
        half = math.pi * p.min_band_px / seer.width_px
        if half < math.pi / 2:
            out = min(out, body.radius_m / math.sin(half))
    return out


def segment_dist(a: FloatArray, b: FloatArray, q: FloatArray) -> FloatArray:
    """Distance from point ``q`` to each segment a -> b[i] (``a`` and ``q`` points, ``b`` (N, 2))."""
    ab = b - a
    n2 = np.einsum("ij,ij->i", ab, ab)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(n2 > 0, (ab @ (q - a)) / n2, 0.0)
    near = a + np.clip(t, 0.0, 1.0)[:, None] * ab
    return np.asarray(np.hypot(*(near - q).T), dtype=np.float64)
