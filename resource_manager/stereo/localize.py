"""Localisation: a floor position, head height and covariance from matched views.

With the best pair (the paper's method) the position comes from
:func:`common.geometry.localize_pair`: triangulation (Eq. 1) or, near
colinearity, size-ratio (Eq. 2), chosen by the crossover of
docs/geometry.md §3. With ``fuse_all`` every view of the person is combined
by least squares (:func:`common.geometry.intersect_rays`).

The head-top height comes from the top elevation: z = z_cam + D·tan(top_elev),
averaged over the views with weights 1/D².

Covariance (first order, docs/geometry.md §2.1): an error δθ1 in camera 1's
bearing moves the intersection along ray 2 by D1·δθ1/sin φ0, and δθ2 moves it
along ray 1 by D2·δθ2/sin φ0; a baseline error δB scales the triangle about O1.
Hence Σ = σ²/sin²φ0 (D1² e2e2ᵀ + D2² e1e1ᵀ) + (σ_B/B)² (p−O1)(p−O1)ᵀ, whose
trace is the error model's σ²(D1²+D2²)/sin²φ0 (the size of ``pair_position_error``).
For size-ratio the error lies along the baseline: 2εD1D2/B (relative width
error ε), and D1·σ across it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from common.arrays import FloatArray
from common.error_model import pair_error_f
from common.geometry import MIN_RAYS, intersect_rays, localize_pair
from common.schema import Method
from resource_manager.views.blobs import Views

__all__ = [
    "MAX_PERSON_WIDTH_M",
    "Measurement",
    "localize_best_pair",
    "localize_least_squares",
    "pair_sigmas",
    "wide_blob",
]

MAX_PERSON_WIDTH_M = 0.75
"""A blob wider than this (metric width at its distance) holds several people (simulated bodies: 0.40-0.52 m)."""

AT_CAMERA_M = 1e-6
"""A point this close to a camera (m) has no direction from it."""


@dataclass(frozen=True, slots=True)
class Measurement:
    """One person's position at the fusion instant, from some views."""

    xy: FloatArray
    """(2,) floor position."""
    cov: FloatArray
    """(2, 2) covariance in m²."""
    height_m: float
    """Head-top height above the floor (0: unknown)."""
    method: Method
    sensors: tuple[str, ...]
    predicted_error_m: float
    """The error model's predicted position error of the views used."""
    blobs: tuple[tuple[str, int], ...]
    """(sensor_id, blob index in its view) of every view used."""


def wide_blob(views: Views, blob: int, distance_m: float) -> bool:
    """Whether blob (entry) ``blob`` is plainly wider than one person at ``distance_m`` (a merged group)."""
    return 2.0 * distance_m * math.tan(0.5 * views.width_rad.item(blob)) > MAX_PERSON_WIDTH_M


def pair_sigmas(sigma_a_rad: float, sigma_b_rad: float, sigma_xy_a: float, sigma_xy_b: float) -> tuple[float, float]:
    """Bearing sigma of the pair of cameras with bearing errors ``sigma_a_rad``, ``sigma_b_rad`` and the baseline
    sigma (non-zero when a pose came from mutual calibration)."""
    return math.hypot(sigma_a_rad, sigma_b_rad) / math.sqrt(2.0), math.hypot(sigma_xy_a, sigma_xy_b)


def _in_view(views: Views, blob: int) -> tuple[str, int]:
    """(sensor id, index in its view) of blob (entry) ``blob``."""
    row = views.view_of.item(blob)
    return views.sensor_ids[row], blob - views.offsets.item(row)


def _height(views: Views, blobs: list[int], xy: FloatArray) -> float:
    x, y = float(xy[0]), float(xy[1])
    num = den = 0.0
    whole = [e for e in blobs if not views.top_cut.item(e)]
    if whole:
        blobs = whole  # a head cut by the image border gives only a lower bound: the other views' heights
    for e in blobs:  # plain floats (.item): two views, numpy per element would cost more
        row = views.view_of.item(e)
        d = math.hypot(x - views.origin.item(row, 0), y - views.origin.item(row, 1))
        if d <= AT_CAMERA_M:
            continue
        z = views.z_m.item(row) + d * math.tan(views.top_elev_rad.item(e))
        w = 1.0 / (d * d)
        num += w * z
        den += w
    return max(0.0, num / den) if den > 0 else 0.0


def localize_best_pair(
    views: Views,
    i: int,
    j: int,
    *,
    sigma_xy_a: float = 0.0,
    sigma_xy_b: float = 0.0,
    width_rel_sigma: float = 0.1,
    min_sigma_m: float = 0.02,
) -> Measurement | None:
    """Localise blob (entry) ``i`` of one camera (a, O1) and blob ``j`` of another (b, O2) (Eq. 1 or Eq. 2); None if
    the rays do not meet."""
    ra, rb = views.view_of.item(i), views.view_of.item(j)
    sigma, sigma_base = pair_sigmas(views.sigma_rad.item(ra), views.sigma_rad.item(rb), sigma_xy_a, sigma_xy_b)
    w1, w2 = views.width_rad.item(i), views.width_rad.item(j)
    sigma_w = width_rel_sigma * 0.5 * (w1 + w2)
    o1, o2 = views.origin[ra], views.origin[rb]
    fix = localize_pair(o1, views.bearing_rad.item(i), w1, o2, views.bearing_rad.item(j), w2, sigma, max(sigma_w, 1e-6))
    if not fix.converges:
        return None
    xy = fix.xy
    x, y = float(xy[0]), float(xy[1])
    if not (math.isfinite(x) and math.isfinite(y)):
        return None
    x1, y1, x2, y2 = float(o1[0]), float(o1[1]), float(o2[0]), float(o2[1])
    base = math.hypot(x2 - x1, y2 - y1)
    d1, d2 = float(fix.d1_m), float(fix.d2_m)
    if fix.method == "size_ratio" and (wide_blob(views, i, d1) or wide_blob(views, j, d2)):
        # Eq. 2 takes the widths for one person's: a merged group's blob puts the fix far off along the baseline.
        return None
    # Covariance as (xx, xy, yy) in plain floats (one small matrix per call: numpy per element costs more).
    if fix.method == "size_ratio":
        ux, uy = (x2 - x1) / max(base, 1e-9), (y2 - y1) / max(base, 1e-9)
        along2 = (2.0 * width_rel_sigma * d1 * d2 / max(base, 1e-9)) ** 2
        across2 = (d1 * sigma) ** 2
        cxx, cxy, cyy = (
            along2 * ux * ux + across2 * uy * uy,
            (along2 - across2) * ux * uy,
            along2 * uy * uy + across2 * ux * ux,
        )
    else:
        s0 = max(abs(math.sin(float(fix.phi0_rad))), 1e-3)
        n1 = max(math.hypot(x - x1, y - y1), 1e-9)
        n2 = max(math.hypot(x - x2, y - y2), 1e-9)
        e1x, e1y, e2x, e2y = (x - x1) / n1, (y - y1) / n1, (x - x2) / n2, (y - y2) / n2
        k = (sigma / s0) ** 2
        cxx = k * (d1 * d1 * e2x * e2x + d2 * d2 * e1x * e1x)
        cxy = k * (d1 * d1 * e2x * e2y + d2 * d2 * e1x * e1y)
        cyy = k * (d1 * d1 * e2y * e2y + d2 * d2 * e1y * e1y)
    if sigma_base > 0 and base > 0:
        kb = (sigma_base / base) ** 2
        rx, ry = x - x1, y - y1
        cxx, cxy, cyy = cxx + kb * rx * rx, cxy + kb * rx * ry, cyy + kb * ry * ry
    m2 = min_sigma_m**2
    cov = np.array([[cxx + m2, cxy], [cxy, cyy + m2]])
    predicted = pair_error_f(x1, y1, x2, y2, x, y, sigma, sigma_base)
    if fix.method == "size_ratio" or not math.isfinite(predicted):
        predicted = math.sqrt((cxx + m2) + (cyy + m2))
    return Measurement(
        xy=xy,
        cov=cov,
        height_m=_height(views, [i, j], xy),
        method="size_ratio" if fix.method == "size_ratio" else "triangulation",
        sensors=(views.sensor_ids[ra], views.sensor_ids[rb]),
        predicted_error_m=predicted,
        blobs=(_in_view(views, i), _in_view(views, j)),
    )


def localize_least_squares(
    views: Views, blobs: list[int], sigma_xy: dict[str, float], min_sigma_m: float = 0.02
) -> Measurement | None:
    """Fuse the blobs (entries) ``blobs`` of one person, one per view, by least squares on the bearing rays; None if
    degenerate."""
    if len(blobs) < MIN_RAYS:
        return None
    rows = [int(views.view_of[e]) for e in blobs]
    origins = np.array([views.origin[r] for r in rows], dtype=np.float64)
    bearings = np.array([float(views.bearing_rad[e]) for e in blobs], dtype=np.float64)
    sigmas = [float(views.sigma_rad[r]) for r in rows]
    try:
        fix = intersect_rays(origins, bearings, np.array(sigmas, dtype=np.float64))
    except Exception:  # GeometryError on parallel rays
        return None
    xy = np.asarray(fix.xy, dtype=np.float64)
    if not np.all(np.isfinite(xy)):
        return None
    cov = np.asarray(fix.cov, dtype=np.float64)
    sensors = tuple(views.sensor_ids[r] for r in rows)
    pose_var = max(sigma_xy.get(sid, 0.0) for sid in sensors) ** 2
    cov = cov + (pose_var + min_sigma_m**2) * np.eye(2)
    return Measurement(
        xy=xy,
        cov=cov,
        height_m=_height(views, blobs, xy),
        method="least_squares",
        sensors=sensors,
        predicted_error_m=math.sqrt(max(float(np.trace(cov)), 0.0)),
        blobs=tuple(_in_view(views, e) for e in blobs),
    )
