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
A ghost lies at a range none of its blobs' feet agree with: the tracker uses a
blob's floor distance, where it has one, as a second measurement beside its
bearing, in assignment and in the update (:mod:`resource_manager.track`).
"""

from __future__ import annotations

import math

import numpy as np

from common.arrays import FloatArray

__all__ = ["MIN_DEPRESSION_RAD", "mono_ranges"]

MIN_DEPRESSION_RAD = math.radians(1.5)
"""Feet closer to the horizon than this give no usable distance (tan ε → 0)."""
PLAUSIBLE_SIGMAS = 3.0
"""A head this many sigmas (people's height spread and the measurement's) from people's mean height is no
person's head: the box's bottom is not their feet."""


def mono_ranges(
    bottom_elev_rad: FloatArray,
    z_m: float,
    sigma_elev_rad: float,
    base_sigma_m: float,
    max_range_m: float,
    *,
    top_elev_rad: FloatArray | None = None,
    height_m: tuple[float, float] | None = None,
    sigma_top_rad: float = 0.0,
) -> tuple[FloatArray, FloatArray]:
    """(floor distance, its 1-sigma) of each blob from its feet elevation; NaN where not observable.

    A box whose bottom is not the feet (a nearer person, or a table, hides them and the detector drew only what
    it saw) puts the person farther than they are, and its top then puts their head at no person's height:
    given ``top_elev_rad`` and ``height_m``, such a box gives no distance.

    Args:
        bottom_elev_rad: (n,) feet elevations (NaN: feet not visible).
        z_m: camera height above the floor.
        sigma_elev_rad: error of one feet elevation.
        base_sigma_m: added to every sigma (the body's extent around the point below the head).
        max_range_m: farther than this is not trusted.
        top_elev_rad: (n,) elevations of the boxes' tops (head tops).
        height_m: people's head-top heights (mean, spread).
        sigma_top_rad: error of one top elevation.
    """
    bottom = np.asarray(bottom_elev_rad, dtype=np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        ok = np.isfinite(bottom) & (bottom < -MIN_DEPRESSION_RAD) & (z_m > 0)
        dist = np.where(ok, z_m / np.tan(-np.where(ok, bottom, -1.0)), np.nan)
        ok &= dist <= max_range_m
        dist = np.where(ok, dist, np.nan)
        sigma = np.where(ok, (dist * dist + z_m * z_m) / max(z_m, 1e-6) * sigma_elev_rad + base_sigma_m, np.nan)
        if top_elev_rad is not None and height_m is not None:
            tan_top = np.tan(np.asarray(top_elev_rad, dtype=np.float64))
            head = z_m + dist * tan_top
            spread = np.hypot(np.hypot(height_m[1], tan_top * sigma), dist * sigma_top_rad * (1.0 + tan_top * tan_top))
            ok &= (head - height_m[0]) * np.sign(z_m - height_m[0]) >= -PLAUSIBLE_SIGMAS * spread
            dist, sigma = np.where(ok, dist, np.nan), np.where(ok, sigma, np.nan)
    return dist, sigma
