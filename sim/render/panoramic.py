"""Painting bodies into a cylindrical panorama, one column at a time.

Each primitive is cast per panorama column: the column's bearing gives a
horizontal ray, intersected exactly with the primitive's horizontal cross
section (an ellipse or circle); the rows it covers follow from the cylindrical
camera's linear-perspective rows, v = v0 - f_v (z - H_c) / t, at the hit
distance t. Horizontal extents come from the exact tangent rays (for a
cylinder of radius R at distance B: the half-angle asin(R/B) that Eq. 3
inverts), and edge pixels are blended by the fraction of the pixel the
silhouette covers, as a real sensor integrates over a pixel. Primitives are
painted far to near (painter's algorithm), which resolves occlusion because
the parts are convex and do not interpenetrate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from common.angles import angle_diff, wrap_angle
from common.arrays import FloatArray
from common.cameras import CylindricalCamera
from sim.render.bodies import Cylinder, Head, Primitive, band_colours, is_hair

__all__ = ["PanoView", "paint_primitives"]

LABEL_COVERAGE = 0.5
"""A pixel's label is a primitive's when it covers at least this fraction of the pixel."""


@dataclass(frozen=True, slots=True)
class PanoView:
    """Where the panoramic camera is: optical centre and heading of its sensor frame."""

    x_m: float
    y_m: float
    z_m: float
    yaw_rad: float


def _to_sensor(view: PanoView, x_m: float, y_m: float) -> tuple[float, float]:
    c, s = math.cos(view.yaw_rad), math.sin(view.yaw_rad)
    dx, dy = x_m - view.x_m, y_m - view.y_m
    return (c * dx + s * dy, -s * dx + c * dy)


def _columns(
    cam: CylindricalCamera, bearing_c: float, d_lo: float, d_hi: float
) -> tuple[FloatArray, FloatArray] | None:
    """Integer columns touched by bearings [bearing_c + d_lo, bearing_c + d_hi] and their coverage."""
    f = cam.f_h_px * cam.direction
    u_c = float(cam.col_from_bearing(bearing_c))
    u_a, u_b = u_c + d_lo * f, u_c + d_hi * f
    u_lo, u_hi = min(u_a, u_b), max(u_a, u_b)
    c0, c1 = math.floor(u_lo + 0.5), math.ceil(u_hi - 0.5)
    if c1 < c0 or c1 - c0 >= cam.width_px:
        return None
    cols = np.arange(c0, c1 + 1, dtype=np.float64)
    cover = np.clip(np.minimum(cols + 0.5, u_hi) - np.maximum(cols - 0.5, u_lo), 0.0, 1.0)
    return cols, cover


def _blend(  # noqa: PLR0917 - one call site, arguments in painting order
    pano: npt.NDArray[np.uint8],
    labels: npt.NDArray[np.int32] | None,
    cols: FloatArray,
    r0: int,
    alpha: npt.NDArray[np.float32],
    colour: npt.NDArray[np.float32],
    label: int,
) -> None:
    """pano[rows, cols] = mix(old, colour, alpha) with column wrap-around."""
    w = pano.shape[1]
    r1 = r0 + alpha.shape[0]
    c0 = int(cols[0]) % w
    if c0 + cols.size <= w:
        sl: slice | npt.NDArray[np.int64] = slice(c0, c0 + cols.size)
    else:
        sl = (cols.astype(np.int64)) % w
    old = pano[r0:r1, sl].astype(np.float32)
    a = alpha[..., None]
    pano[r0:r1, sl] = (old + a * (colour - old) + 0.5).astype(np.uint8)
    if labels is not None:
        sub = labels[r0:r1, sl]
        labels[r0:r1, sl] = np.where(alpha >= LABEL_COVERAGE, label, sub)


def _coverage(
    cam: CylindricalCamera, v_top: FloatArray, v_bot: FloatArray, cover: FloatArray
) -> tuple[int, FloatArray, npt.NDArray[np.float32]] | None:
    """The rows a shape spans per column, and each pixel's coverage (vertical overlap × column cover).

    Returns ``(r0, v, alpha)``: the first row, the row centres as a column vector, and alpha of shape
    (rows, columns); None when the shape falls outside the panorama.
    """
    r0 = max(0, math.floor(float(np.min(v_top)) + 0.5))
    r1 = min(cam.height_px - 1, math.ceil(float(np.max(v_bot)) - 0.5))
    if r1 < r0:
        return None
    v = np.arange(r0, r1 + 1, dtype=np.float64)[:, None]
    cov_v = np.clip(np.minimum(v + 0.5, v_bot[None, :]) - np.maximum(v - 0.5, v_top[None, :]), 0.0, 1.0)
    return r0, v, (cov_v * cover[None, :]).astype(np.float32)


def _paint_cylinder(
    pano: npt.NDArray[np.uint8],
    labels: npt.NDArray[np.int32] | None,
    cam: CylindricalCamera,
    view: PanoView,
    c: Cylinder,
) -> None:
    sx, sy = _to_sensor(view, c.x_m, c.y_m)
    hd = c.heading_rad - view.yaw_rad
    ch, sh = math.cos(hd), math.sin(hd)
    # Camera in the ellipse's local frame (x' along the heading, semi-axis b; y' across, semi-axis a).
    px, py = -(ch * sx + sh * sy), -(-sh * sx + ch * sy)
    qx, qy = px / c.b_m, py / c.a_m
    qn = math.hypot(qx, qy)
    if qn <= 1.0 + 1e-9:
        return  # the camera is inside the part
    # Exact tangent rays: tangents from q to the unit circle, mapped back by the affine scaling.
    phi, delta = math.atan2(qy, qx), math.acos(1.0 / qn)
    bearing_c = math.atan2(sy, sx)
    spans = []
    for sgn in (-1.0, 1.0):
        tx, ty = c.b_m * math.cos(phi + sgn * delta), c.a_m * math.sin(phi + sgn * delta)
        wx, wy = sx + ch * tx - sh * ty, sy + sh * tx + ch * ty
        spans.append(angle_diff(math.atan2(wy, wx), bearing_c))
    got = _columns(cam, bearing_c, min(spans), max(spans))
    if got is None:
        return
    cols, cover = got
    theta = np.asarray(cam.bearing_from_col(cols), dtype=np.float64)
    dx, dy = np.cos(theta), np.sin(theta)
    dlx, dly = (ch * dx + sh * dy) / c.b_m, (-sh * dx + ch * dy) / c.a_m
    a2 = dlx * dlx + dly * dly
    b2 = 2.0 * (qx * dlx + qy * dly)
    disc = np.maximum(b2 * b2 - 4.0 * a2 * (qn * qn - 1.0), 0.0)
    root = np.sqrt(disc)
    t_near, t_far = (-b2 - root) / (2.0 * a2), (-b2 + root) / (2.0 * a2)
    if float(np.max(t_far)) <= 0.0:
        return
    t_near = np.maximum(t_near, 1e-3)
    fv, v0, oz = cam.f_v_px, cam.v0_px, view.z_m
    v_top = v0 - fv * (c.z1_m - oz) / (t_far if c.z1_m < oz else t_near)
    v_bot = v0 - fv * (c.z0_m - oz) / (t_far if c.z0_m > oz else t_near)
    spanned = _coverage(cam, v_top, v_bot, cover)
    if spanned is None:
        return
    r0, v, alpha = spanned
    # Shading: Lambert toward the viewer on the side, caps a little darker, lit from above.
    hx, hy = qx + t_near * dlx, qy + t_near * dly  # unit-circle coordinates of the hit
    nx, ny = hx / c.b_m, hy / c.a_m
    nn = np.hypot(nx, ny) + 1e-12
    lam = np.clip(-(nx * dlx * c.b_m + ny * dly * c.a_m) / nn, 0.0, 1.0)
    z = oz + (v0 - v) * t_near[None, :] / fv
    cap = (z > c.z1_m) | (z < c.z0_m)
    zc = np.clip(z, c.z0_m, c.z1_m)
    colour = band_colours(c.bands, zc)
    span = max(c.z1_m - c.z0_m, 1e-6)
    shade = (1.0 - c.shade_depth + c.shade_depth * np.sqrt(lam))[None, :] * (0.88 + 0.12 * (zc - c.z0_m) / span)
    shade = np.where(cap, 0.8, shade)
    colour *= shade[..., None].astype(np.float32)
    _blend(pano, labels, cols, r0, alpha, colour, c.label)


def _paint_head(
    pano: npt.NDArray[np.uint8], labels: npt.NDArray[np.int32] | None, cam: CylindricalCamera, view: PanoView, h: Head
) -> None:
    sx, sy = _to_sensor(view, h.x_m, h.y_m)
    d = math.hypot(sx, sy)
    if d <= h.rh_m * 1.01:
        return
    half = math.asin(h.rh_m / d)
    bearing_c = math.atan2(sy, sx)
    got = _columns(cam, bearing_c, -half, half)
    if got is None:
        return
    cols, cover = got
    theta = np.asarray(cam.bearing_from_col(cols), dtype=np.float64)
    dth = wrap_angle(theta - bearing_c)
    p = d * np.sin(dth) / h.rh_m
    f = np.sqrt(np.clip(1.0 - p * p, 0.0, 1.0))
    dist = d * np.cos(dth)
    fv, v0, oz = cam.f_v_px, cam.v0_px, view.z_m
    v_top = v0 - fv * (h.zc_m + h.rv_m * f - oz) / dist
    v_bot = v0 - fv * (h.zc_m - h.rv_m * f - oz) / dist
    spanned = _coverage(cam, v_top, v_bot, cover)
    if spanned is None:
        return
    r0, v, alpha = spanned
    # Surface normal (horizontal part) at the visible point, to choose face or hair.
    t_hit = dist - h.rh_m * f
    hx = (t_hit * np.cos(theta) - sx) / h.rh_m
    hy = (t_hit * np.sin(theta) - sy) / h.rh_m
    hd = h.heading_rad - view.yaw_rad
    facing = (hx * math.cos(hd) + hy * math.sin(hd))[None, :]
    zeta = (oz + (v0 - v) * dist[None, :] / fv - h.zc_m) / h.rv_m
    hair = is_hair(zeta, facing)
    colour = np.where(hair[..., None], np.asarray(h.hair_bgr, np.float32), np.asarray(h.skin_bgr, np.float32))
    shade = 0.55 + 0.45 * f[None, :] * np.sqrt(np.clip(1.0 - 0.7 * zeta * zeta, 0.0, 1.0))
    _blend(pano, labels, cols, r0, alpha, (colour * shade[..., None]).astype(np.float32), h.label)


def paint_primitives(
    pano: npt.NDArray[np.uint8],
    cam: CylindricalCamera,
    view: PanoView,
    prims: list[Primitive],
    labels: npt.NDArray[np.int32] | None = None,
) -> None:
    """Paint primitives into ``pano`` (BGR, in place), far to near; optionally also their labels."""
    order = sorted(range(len(prims)), key=lambda i: -math.hypot(prims[i].x_m - view.x_m, prims[i].y_m - view.y_m))
    for i in order:
        prim = prims[i]
        if isinstance(prim, Head):
            _paint_head(pano, labels, cam, view, prim)
        else:
            _paint_cylinder(pano, labels, cam, view, prim)
