"""Annular (PAL) image <-> cylindrical panorama: the paper's Steps 1 and 2.

A panoramic annular lens pointing up images the 360 deg horizon as a ring.
Vertical world lines image as radial lines through the ring centre (Step 1,
:func:`center_from_lines`); the radius is a non-linear function of elevation,
approximated by a 2nd-order polynomial of the rectified panorama row (Step 2,
:func:`fit_radial_polynomial`)::

    r   = a0 + a1 v + a2 v^2                 (radius in the annular image, px)
    psi = psi0 + direction * 2 pi u / W      (angle in the annular image)
    x   = cx + r cos(psi),   y = cy - r sin(psi)

so a panorama pixel (u, v) comes from annular pixel (x, y). Pixel centres are
at integer coordinates, as in ``cv2.remap``.

Unwarping an annular image::

    map_x, map_y = model.unwarp_maps()
    pano = cv2.remap(annular, map_x, map_y, cv2.INTER_LINEAR)

Rendering a panorama into an annular image (the simulator) -- append column 0
so interpolation across the u = W seam wraps; pixels outside the ring map to -1
and take the border value::

    map_x, map_y = model.warp_maps()
    padded = np.concatenate([pano, pano[:, :1]], axis=1)
    annular = cv2.remap(padded, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from common.angles import TWO_PI
from common.arrays import FloatArray
from common.cylindrical import CylindricalCamera
from common.errors import CalibrationError, ConfigError

__all__ = ["AnnularModel", "center_from_lines", "design_pal", "fit_radial_polynomial"]

MIN_SIZE_PX = 2
"""An image or panorama narrower or lower than this many pixels is refused."""
HALF_PX = 0.5
"""Pixel centres are at integers: a row covers +-0.5 around its index."""
MAX_ELEV_DEG = 89.0
"""A lens's field of view must stay below +-this elevation (tan grows without bound at 90 deg)."""
MIN_LINES = 2
"""Step 1: the ring centre is the intersection of at least this many imaged vertical lines."""
MIN_LINE_POINTS = 2
"""...each given by at least this many points."""
COINCIDENT_PX = 1e-12
"""A line whose points spread less than this (px) is a single point."""
PARALLEL_RATIO = 1e-6
"""Lines whose least-squares system has a singular-value ratio below this are (nearly) parallel."""
POLY_TERMS = 3
"""Step 2: r = a0 + a1 v + a2 v^2 has three terms, so it needs three distinct rows."""


@dataclass(frozen=True, slots=True)
class AnnularModel:
    """Polar mapping between an annular image and its cylindrical panorama (Steps 1-2)."""

    image_w: int
    image_h: int
    cx_px: float
    """Ring centre column in the annular image (Step 1)."""
    cy_px: float
    a0: float
    """r(v) = a0 + a1 v + a2 v^2: radius in px of panorama row v (Step 2)."""
    a1: float
    a2: float
    pano_w: int
    pano_h: int
    psi0_rad: float = 0.0
    """Annular-image angle (counter-clockwise from +x, y up) of panorama column 0."""
    direction: int = 1
    """+1: psi grows with the column; -1: it decreases."""

    def __post_init__(self) -> None:
        if min(self.image_w, self.image_h, self.pano_w, self.pano_h) < MIN_SIZE_PX:
            raise ConfigError(
                f"image and panorama sizes must be >= 2 px, got {self.image_w}x{self.image_h}, "
                f"{self.pano_w}x{self.pano_h}"
            )
        if self.direction not in (1, -1):
            raise ConfigError(f"direction must be +1 or -1, got {self.direction}")
        coefs = (self.cx_px, self.cy_px, self.a0, self.a1, self.a2, self.psi0_rad)
        if not all(math.isfinite(c) for c in coefs):
            raise ConfigError(f"annular model parameters must be finite, got {coefs}")
        lo, hi = -0.5, self.pano_h - 0.5
        # r(v) must be positive and monotonic over the panorama rows, or the inverse is ambiguous.
        d_lo, d_hi = self.a1 + 2 * self.a2 * lo, self.a1 + 2 * self.a2 * hi
        if d_lo * d_hi <= 0:
            raise ConfigError(
                f"radius polynomial must be monotonic over rows [{lo}, {hi}]: dr/dv goes {d_lo:.4g} -> {d_hi:.4g}"
            )
        if min(self._radius(lo), self._radius(hi)) <= 0:
            raise ConfigError(f"radius polynomial must be > 0 over the panorama, got r({lo})={self._radius(lo):.4g}")

    def _radius(self, v: float) -> float:
        return self.a0 + self.a1 * v + self.a2 * v * v

    @property
    def radius_range_px(self) -> tuple[float, float]:
        """(inner, outer) radius of the ring covered by the panorama rows."""
        r = (self._radius(-0.5), self._radius(self.pano_h - 0.5))
        return min(r), max(r)

    def annular_from_pano(self, u: npt.ArrayLike, v: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Annular-image (x, y) of panorama point(s) (u, v)."""
        uu = np.asarray(u, dtype=np.float64)
        vv = np.asarray(v, dtype=np.float64)
        r = self.a0 + self.a1 * vv + self.a2 * vv * vv
        psi = self.psi0_rad + self.direction * TWO_PI * uu / self.pano_w
        return self.cx_px + r * np.cos(psi), self.cy_px - r * np.sin(psi)

    def pano_from_annular(self, x: npt.ArrayLike, y: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Panorama (u, v) of annular point(s) (x, y); u in [0, pano_w). v is NaN where no real root exists.

        Rows outside [-0.5, pano_h - 0.5] are returned as computed (the caller decides what is outside).
        """
        dx = np.asarray(x, dtype=np.float64) - self.cx_px
        dy = self.cy_px - np.asarray(y, dtype=np.float64)
        r = np.hypot(dx, dy)
        psi = np.arctan2(dy, dx)
        u = np.mod(self.direction * (psi - self.psi0_rad) * self.pano_w / TWO_PI, self.pano_w)
        u = np.where(u >= self.pano_w, 0.0, u)
        # Root of a2 v^2 + a1 v - (r - a0) = 0 on the branch continuous with the linear solution,
        # in the cancellation-free form 2c / (a1 + sign(a1) sqrt(a1^2 + 4 a2 c)).
        c = r - self.a0
        disc = self.a1 * self.a1 + 4.0 * self.a2 * c
        sgn = 1.0 if self.a1 >= 0 else -1.0
        with np.errstate(invalid="ignore", divide="ignore"):
            den = self.a1 + sgn * np.sqrt(disc)
            v = np.where(disc >= 0, 2.0 * c / den, np.nan)
        return u, v

    def unwarp_maps(self) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.float32]]:
        """float32 maps (pano_h, pano_w) for ``cv2.remap(annular, map_x, map_y, INTER_LINEAR)`` -> panorama."""
        vv, uu = np.mgrid[0 : self.pano_h, 0 : self.pano_w].astype(np.float64)
        x, y = self.annular_from_pano(uu, vv)
        return x.astype(np.float32), y.astype(np.float32)

    def warp_maps(self) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.float32]]:
        """float32 maps (image_h, image_w) rendering a panorama into the annular image; -1 outside the ring.

        u lies in [0, pano_w): remap from the panorama with column 0 appended (see module docstring).
        """
        yy, xx = np.mgrid[0 : self.image_h, 0 : self.image_w].astype(np.float64)
        u, v = self.pano_from_annular(xx, yy)
        inside = np.isfinite(v) & (v >= -HALF_PX) & (v <= self.pano_h - HALF_PX)
        map_x = np.where(inside, u, -1.0).astype(np.float32)
        map_y = np.where(inside, np.clip(v, 0.0, self.pano_h - 1.0), -1.0).astype(np.float32)
        return map_x, map_y


def design_pal(
    image_size: tuple[int, int] = (768, 576),
    pano_size: tuple[int, int] = (1080, 162),
    elev_min_deg: float = -15.0,
    elev_max_deg: float = 20.0,
    height_m: float = 1.1,
) -> tuple[AnnularModel, CylindricalCamera]:
    """A PAL-like lens (the paper's Fig. 1): annular model plus the rectified cylindrical camera.

    The cylindrical camera's rows are linear-perspective in elevation and span
    exactly [elev_min, elev_max] from the bottom edge of the last row to the top
    edge of row 0. The lens maps elevation to image radius non-linearly: the
    radius is a genuine 2nd-order polynomial of the rectified row (a2 != 0, the
    mid row sits ~4 % of the ring width off the linear chord), higher elevations
    further out. The ring centre is a few pixels off the image centre, as on a
    real camera, and the outer radius leaves a small margin inside the image.

    Args:
        image_size: (width, height) of the annular image.
        pano_size: (width, height) of the panorama.
        elev_min_deg: lowest elevation seen (bottom of the panorama).
        elev_max_deg: highest elevation seen (top of the panorama).
        height_m: camera height above the floor for the cylindrical camera.
    """
    (img_w, img_h), (pano_w, pano_h) = image_size, pano_size
    if not -MAX_ELEV_DEG < elev_min_deg < elev_max_deg < MAX_ELEV_DEG:
        raise ConfigError(f"need -89 < elev_min_deg < elev_max_deg < 89, got {elev_min_deg}, {elev_max_deg}")
    t_lo, t_hi = math.tan(math.radians(elev_min_deg)), math.tan(math.radians(elev_max_deg))
    f_v = pano_h / (t_hi - t_lo)
    v0 = -0.5 + f_v * t_hi
    camera = CylindricalCamera(
        width_px=pano_w, height_px=pano_h, f_v_px=f_v, v0_px=v0, height_m=height_m, direction=1, bearing0_rad=0.0
    )
    cx = (img_w - 1) / 2.0 + 0.013 * min(img_w, img_h) / 2.0
    cy = (img_h - 1) / 2.0 - 0.008 * min(img_w, img_h) / 2.0
    margin = max(abs(cx - (img_w - 1) / 2.0), abs(cy - (img_h - 1) / 2.0)) + 4.0
    r_out = min(img_w, img_h) / 2.0 - margin
    r_in = 0.38 * r_out
    # Radius through the three rows top edge / middle / bottom edge: outer, bowed, inner.
    v_top, v_bot = -0.5, pano_h - 0.5
    v_mid = (v_top + v_bot) / 2.0
    bow = 0.04 * (r_out - r_in)
    a2, a1, a0 = np.polyfit([v_top, v_mid, v_bot], [r_out, (r_out + r_in) / 2.0 + bow, r_in], 2)
    model = AnnularModel(
        image_w=img_w,
        image_h=img_h,
        cx_px=cx,
        cy_px=cy,
        a0=float(a0),
        a1=float(a1),
        a2=float(a2),
        pano_w=pano_w,
        pano_h=pano_h,
        psi0_rad=0.0,
        direction=1,
    )
    return model, camera


def center_from_lines(lines: list[npt.NDArray[np.float64]] | list[npt.ArrayLike]) -> tuple[float, float]:
    """Ring centre from >= 2 imaged vertical lines (Step 1): least-squares intersection.

    Each line's points are fitted by total least squares (n_i . x = c_i); the
    centre minimises sum_i (n_i . x - c_i)^2 (exact for 2 lines).

    Raises:
        CalibrationError: fewer than 2 lines, a line with < 2 distinct points, or all lines parallel.
    """
    if len(lines) < MIN_LINES:
        raise CalibrationError(f"centre determination needs >= 2 lines, got {len(lines)}")
    normals, offsets = [], []
    for i, pts in enumerate(lines):
        p = np.asarray(pts, dtype=np.float64)
        if p.shape[1:] != (2,) or len(p) < MIN_LINE_POINTS or not np.all(np.isfinite(p)):
            raise CalibrationError(f"line {i}: expected (N>=2, 2) finite points, got shape {p.shape}")
        m = p.mean(axis=0)
        _, s, vt = np.linalg.svd(p - m)
        if s[0] <= COINCIDENT_PX:
            raise CalibrationError(f"line {i}: all points coincide")
        n = vt[1]  # normal = direction of least spread
        normals.append(n)
        offsets.append(float(n @ m))
    a = np.asarray(normals)
    sol, _, rank, sv = np.linalg.lstsq(a, np.asarray(offsets), rcond=None)
    if rank < MIN_LINES or sv[-1] < PARALLEL_RATIO * sv[0]:
        raise CalibrationError("the lines are (nearly) parallel: no unique intersection")
    return float(sol[0]), float(sol[1])


def fit_radial_polynomial(rows_v: npt.ArrayLike, radii_px: npt.ArrayLike) -> tuple[float, float, float]:
    """Least-squares r = a0 + a1 v + a2 v^2 from >= 3 (rectified row, radius) pairs (Step 2).

    ``rows_v`` are the rows where known elevations should land in the rectified
    panorama (v0 - f_v tan eps); ``radii_px`` are the radii at which they were
    observed in the annular image.

    Raises:
        CalibrationError: fewer than 3 pairs, mismatched lengths, or fewer than 3 distinct rows.
    """
    v = np.asarray(rows_v, dtype=np.float64).ravel()
    r = np.asarray(radii_px, dtype=np.float64).ravel()
    if v.shape != r.shape:
        raise CalibrationError(f"rows and radii must have the same length, got {v.size} and {r.size}")
    if v.size < POLY_TERMS:
        raise CalibrationError(f"the 2nd-order polynomial needs >= 3 point pairs, got {v.size}")
    if not (np.all(np.isfinite(v)) and np.all(np.isfinite(r))):
        raise CalibrationError("rows and radii must be finite")
    a = np.column_stack([np.ones_like(v), v, v * v])
    sol, _, rank, _ = np.linalg.lstsq(a, r, rcond=None)
    if rank < POLY_TERMS:
        raise CalibrationError(f"need >= 3 distinct rows, got rank {rank}")
    return float(sol[0]), float(sol[1]), float(sol[2])
