"""Painting bodies into a perspective (PTZ) image by per-pixel ray casting with a depth buffer.

Each pixel has a world ray (from the pinhole model of the current pan, tilt
and zoom), written as a unit horizontal direction (dx, dy) and a slope, so the
ray parameter t is the horizontal distance (the same depth the room casting
uses). For every primitive only the pixels inside its projected bounding box
are tested: a vertical elliptic cylinder is the intersection of an elliptic
tube (a quadratic in t) and a height slab; a head is an ellipsoid (a sphere
after scaling z). A pixel takes a primitive's colour where the entry distance
is nearer than what the depth buffer holds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from common.arrays import FloatArray
from common.cameras import PinholeCamera
from sim.render.bodies import Cylinder, Head, Primitive, band_colours, is_hair

__all__ = ["RayGrid", "paint_primitives_rays"]

FLAT_SLOPE = 1e-12
"""A ray whose slope is below this is horizontal: it never leaves a cylinder's height band."""
NEAR_M = 1e-3
"""Surfaces nearer than this along a ray are behind the lens: not seen."""


@dataclass(frozen=True, slots=True)
class RayGrid:
    """Per-pixel rays of a perspective camera (arrays shaped (height, width))."""

    origin_xyz: tuple[float, float, float]
    dir_x: FloatArray
    dir_y: FloatArray
    slope: FloatArray
    """Rise per metre of horizontal travel."""
    pinhole: PinholeCamera


def _bbox(grid: RayGrid, prim: Primitive) -> tuple[int, int, int, int] | None:
    if isinstance(prim, Head):
        r, z0, z1 = prim.rh_m, prim.zc_m - prim.rv_m, prim.zc_m + prim.rv_m
    else:
        r, z0, z1 = max(prim.a_m, prim.b_m), prim.z0_m, prim.z1_m
    xs = (prim.x_m - r, prim.x_m + r)
    ys = (prim.y_m - r, prim.y_m + r)
    corners = np.array([(x, y, z) for x in xs for y in ys for z in (z0, z1)], dtype=np.float64)
    uv, in_front = grid.pinhole.project(corners)
    h, w = grid.dir_x.shape
    if not np.any(in_front):
        return None
    if not np.all(in_front):
        return (0, w, 0, h)  # straddles the camera plane: test everything
    x0, y0 = np.floor(uv.min(axis=0)).astype(int) - 1
    x1, y1 = np.ceil(uv.max(axis=0)).astype(int) + 2
    x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, w), min(y1, h)
    return None if x1 <= x0 or y1 <= y0 else (x0, x1, y0, y1)


def _cylinder(
    origin: tuple[float, float, float], dx: FloatArray, dy: FloatArray, slope: FloatArray, c: Cylinder
) -> tuple[npt.NDArray[np.bool_], FloatArray, npt.NDArray[np.float32]]:
    ox, oy, oz = origin
    ch, sh = math.cos(c.heading_rad), math.sin(c.heading_rad)
    rx, ry = ox - c.x_m, oy - c.y_m
    qx, qy = (ch * rx + sh * ry) / c.b_m, (-sh * rx + ch * ry) / c.a_m
    dlx, dly = (ch * dx + sh * dy) / c.b_m, (-sh * dx + ch * dy) / c.a_m
    a2 = dlx * dlx + dly * dly
    b2 = 2.0 * (qx * dlx + qy * dly)
    disc = b2 * b2 - 4.0 * a2 * (qx * qx + qy * qy - 1.0)
    root = np.sqrt(np.maximum(disc, 0.0))
    t_near, t_far = (-b2 - root) / (2.0 * a2), (-b2 + root) / (2.0 * a2)
    with np.errstate(divide="ignore", invalid="ignore"):
        ta, tb = (c.z0_m - oz) / slope, (c.z1_m - oz) / slope
    flat = np.abs(slope) < FLAT_SLOPE
    inside_slab = c.z0_m <= oz <= c.z1_m
    tz0 = np.where(flat, -np.inf if inside_slab else np.inf, np.minimum(ta, tb))
    tz1 = np.where(flat, np.inf if inside_slab else -np.inf, np.maximum(ta, tb))
    entry = np.maximum(t_near, tz0)
    hit = (disc >= 0.0) & (entry <= np.minimum(t_far, tz1)) & (entry > NEAR_M)
    z = np.clip(oz + entry * slope, c.z0_m, c.z1_m)
    colour = band_colours(c.bands, z)
    hx, hy = qx + t_near * dlx, qy + t_near * dly
    nx, ny = hx / c.b_m, hy / c.a_m
    lam = np.clip(-(nx * dlx * c.b_m + ny * dly * c.a_m) / (np.hypot(nx, ny) + 1e-12), 0.0, 1.0)
    span = max(c.z1_m - c.z0_m, 1e-6)
    side = (1.0 - c.shade_depth + c.shade_depth * np.sqrt(lam)) * (0.88 + 0.12 * (z - c.z0_m) / span)
    shade = np.where(t_near >= tz0, side, 0.8)
    colour *= shade[..., None].astype(np.float32)
    return hit, entry, colour


def _head(
    origin: tuple[float, float, float], dx: FloatArray, dy: FloatArray, slope: FloatArray, h: Head
) -> tuple[npt.NDArray[np.bool_], FloatArray, npt.NDArray[np.float32]]:
    ox, oy, oz = origin
    k = h.rh_m / h.rv_m
    cx, cy, cz = ox - h.x_m, oy - h.y_m, (oz - h.zc_m) * k
    sz = slope * k
    a2 = 1.0 + sz * sz
    b2 = 2.0 * (cx * dx + cy * dy + cz * sz)
    disc = b2 * b2 - 4.0 * a2 * (cx * cx + cy * cy + cz * cz - h.rh_m * h.rh_m)
    t = (-b2 - np.sqrt(np.maximum(disc, 0.0))) / (2.0 * a2)
    hit = (disc >= 0.0) & (t > NEAR_M)
    nx, ny, nz = (cx + t * dx) / h.rh_m, (cy + t * dy) / h.rh_m, (cz + t * sz) / h.rh_m
    facing = nx * math.cos(h.heading_rad) + ny * math.sin(h.heading_rad)
    hair = is_hair(nz, facing)
    colour = np.where(hair[..., None], np.asarray(h.hair_bgr, np.float32), np.asarray(h.skin_bgr, np.float32))
    lam = np.clip(-(nx * dx + ny * dy + nz * sz) / np.sqrt(a2), 0.0, 1.0)
    colour *= (0.5 + 0.5 * lam)[..., None].astype(np.float32)
    return hit, t, colour


def paint_primitives_rays(
    img: npt.NDArray[np.uint8], depth: npt.NDArray[np.float32], grid: RayGrid, prims: list[Primitive]
) -> None:
    """Paint primitives into ``img`` (BGR, in place) wherever they are nearer than ``depth`` (updated)."""
    for prim in prims:
        box = _bbox(grid, prim)
        if box is None:
            continue
        x0, x1, y0, y1 = box
        dx, dy, sl = grid.dir_x[y0:y1, x0:x1], grid.dir_y[y0:y1, x0:x1], grid.slope[y0:y1, x0:x1]
        if isinstance(prim, Head):
            hit, t, colour = _head(grid.origin_xyz, dx, dy, sl, prim)
        else:
            hit, t, colour = _cylinder(grid.origin_xyz, dx, dy, sl, prim)
        zb = depth[y0:y1, x0:x1]
        win = hit & (t < zb)
        if not np.any(win):
            continue
        zb[win] = t[win]
        sub = img[y0:y1, x0:x1]
        sub[win] = np.clip(colour[win] + 0.5, 0, 255).astype(np.uint8)
