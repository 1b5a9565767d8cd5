"""Monocular floor positions: a calibrated perspective camera sees where a person stands.

A fixed perspective camera with a known pose (height ``z`` above the floor) that
sees a person's feet at elevation ε < 0 (the box bottom) places the person at
floor distance ``D = z / tan(-ε)`` along the bearing: one view alone gives a
position (the paper's panoramic cameras have it too, ``floor_distance``, but
their feet rows are too coarse to rely on). Its error is mostly radial:
``∂D/∂ε = (D² + z²) / z``, so ``σ_D = (D² + z²)/z · σ_ε + σ_0`` (σ_0: the body's
extent, the box bottom is not exactly below the head); across the ray the
bearing error gives ``D·σ_θ``.

In crowds the bearing rays of different people cross in many places (ghosts).
A ghost lies at a range none of its blobs' feet agree with, so the manager
uses these ranges (1) to gate which blob supports a track, (2) to veto pair
fixes and births whose range disagrees with a blob's feet, and (3) to keep a
track on its person by the views' floor points when no pair localises it.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from resource_manager.localize import Measurement
from resource_manager.match import ViewBlobs

__all__ = ["MIN_DEPRESSION_RAD", "mono_measurement", "mono_ranges", "range_mismatch"]

FloatArray = npt.NDArray[np.float64]
MIN_DEPRESSION_RAD = math.radians(1.5)
"""Feet closer to the horizon than this give no usable distance (tan ε → 0)."""


def mono_ranges(
    bottom_elev_rad: FloatArray, z_m: float, sigma_elev_rad: float, base_sigma_m: float, max_range_m: float
) -> tuple[FloatArray, FloatArray]:
    """(floor distance, its 1-sigma) of each blob from its feet elevation; NaN where not observable.

    Args:
        bottom_elev_rad: (n,) feet elevations (NaN: feet not visible).
        z_m: camera height above the floor.
        sigma_elev_rad: error of one feet elevation.
        base_sigma_m: added to every sigma (the body's extent around the point below the head).
        max_range_m: farther than this is not trusted.
    """
    bottom = np.asarray(bottom_elev_rad, dtype=np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        ok = np.isfinite(bottom) & (bottom < -MIN_DEPRESSION_RAD) & (z_m > 0)
        dist = np.where(ok, z_m / np.tan(-np.where(ok, bottom, -1.0)), np.nan)
        ok &= dist <= max_range_m
        dist = np.where(ok, dist, np.nan)
        sigma = np.where(ok, (dist * dist + z_m * z_m) / max(z_m, 1e-6) * sigma_elev_rad + base_sigma_m, np.nan)
    return dist, sigma


def range_mismatch(v: ViewBlobs, i: int, xy: FloatArray, extra_sigma_m: float = 0.0) -> float:
    """|distance of ``xy`` from the camera - the blob's floor distance| in sigmas (0 when unknown)."""
    if v.mono_range_m is None or v.mono_sigma_m is None:
        return 0.0
    d_mono = float(v.mono_range_m[i])
    if not math.isfinite(d_mono):
        return 0.0
    d = math.hypot(float(xy[0] - v.origin_xy[0]), float(xy[1] - v.origin_xy[1]))
    s = math.hypot(float(v.mono_sigma_m[i]), extra_sigma_m)
    return abs(d - d_mono) / max(s, 1e-6)


def mono_measurement(views: list[tuple[ViewBlobs, int]], min_sigma_m: float = 0.02) -> Measurement | None:
    """Fuse the floor points of the given views (inverse covariance); None if none has one.

    Each point's covariance is σ_D² along its ray and (D σ_θ)² across it.
    """
    info = np.zeros((2, 2))
    vec = np.zeros(2)
    used: list[tuple[ViewBlobs, int]] = []
    for v, i in views:
        if v.mono_range_m is None or v.mono_sigma_m is None or not math.isfinite(float(v.mono_range_m[i])):
            continue
        d, s_r = float(v.mono_range_m[i]), float(v.mono_sigma_m[i])
        b = float(v.bearing_rad[i])
        u = np.array([math.cos(b), math.sin(b)])
        n = np.array([-u[1], u[0]])
        p = v.origin_xy + d * u
        s_t = max(d * v.sigma_rad, 1e-3)
        w = np.outer(u, u) / s_r**2 + np.outer(n, n) / s_t**2
        info += w
        vec += w @ p
        used.append((v, i))
    if not used:
        return None
    cov = np.linalg.inv(info)
    xy = cov @ vec
    cov = cov + min_sigma_m**2 * np.eye(2)
    height = 0.0
    num = den = 0.0
    for v, i in used:
        dd = float(np.hypot(*(xy - v.origin_xy)))
        if dd > 1e-6:
            num += (v.z_m + dd * math.tan(float(v.top_elev_rad[i]))) / dd**2
            den += 1.0 / dd**2
    if den > 0:
        height = max(0.0, num / den)
    return Measurement(
        xy=xy,
        cov=cov,
        height_m=height,
        method="least_squares",  # a fusion of floor points (the schema has no "monocular" method)
        sensors=tuple(v.sensor_id for v, _ in used),
        predicted_error_m=math.sqrt(float(np.trace(cov))),
        blobs=tuple((v.sensor_id, i) for v, i in used),
    )
