"""The cylindrical virtual camera of the paper's Step 3 and its calibration.

After unwarping and distortion rectification (Steps 1-2, :mod:`common.annular`)
a panoramic image is a cylinder: the projection is circular horizontally and
linear-perspective vertically. Four parameters describe it (paper, Step 3):

* ``f_h`` -- the cylinder radius in pixels, ``width_px / 2 pi`` (one full turn
  per panorama width);
* ``f_v`` -- the vertical "focal length" in pixels;
* ``v0`` -- the row of the horizon circle;
* ``H_c`` -- the height of the virtual viewpoint above the floor.

Sensor frame: x along the bearing of column 0 (plus ``bearing0_rad``), y 90 deg
counter-clockwise, z up with z = height above the floor. Pixel coordinates are
continuous, with the centre of pixel (column u, row v) at integer (u, v), the
same convention as ``cv2.remap``.

Formulas (docs/geometry.md section 5)::

    u = u0 + s_u f_h atan2(Y, X)   (mod W)      theta = s_u (u - u0) / f_h
    v = v0 - f_v (Z - H_c) / rho                tan(eps) = (v0 - v) / f_v
    rho_floor = f_v H_c / (v_foot - v0)         Z = H_c + rho (v0 - v) / f_v
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, overload

import numpy as np
import numpy.typing as npt

from common.angles import TWO_PI, wrap_angle
from common.arrays import FloatArray
from common.errors import CalibrationError, ConfigError
from common.schema import PanoramicModel

__all__ = ["CylindricalCalibration", "CylindricalCamera", "calibrate_cylindrical"]

MIN_PANO_PX = 8
"""A panorama smaller than this in either direction is refused."""
CALIB_UNKNOWNS = 3
"""Step 3 solves (v0, f_v, f_v H_c) by least squares: at least three known points, in general position."""
ON_AXIS_M = 1e-9
"""A calibration point closer than this to the camera's vertical axis has no bearing."""


def _out(x: npt.ArrayLike, like: npt.ArrayLike) -> Any:
    """Return a Python float when the caller passed a scalar, else an array."""
    if np.ndim(like) == 0:
        return float(np.asarray(x))
    return np.asarray(x, dtype=np.float64)


@dataclass(frozen=True, slots=True)
class CylindricalCamera:
    """The 4-parameter cylindrical virtual camera (paper, Step 3).

    Every method accepts a float or a numpy array and returns the same kind.
    """

    width_px: int
    """Panorama width; one full turn."""
    height_px: int
    f_v_px: float
    """Vertical focal length (pixels per unit of tan(elevation))."""
    v0_px: float
    """Row of the horizon circle (elevation 0)."""
    height_m: float
    """Height of the virtual viewpoint above the floor (H_c)."""
    direction: int = 1
    """+1: bearing grows with the column (counter-clockwise); -1: it decreases."""
    bearing0_rad: float = 0.0
    """Sensor-frame bearing of column 0 (0 by definition of the sensor frame)."""

    def __post_init__(self) -> None:
        if min(self.width_px, self.height_px) < MIN_PANO_PX:
            raise ConfigError(f"panorama size must be >= 8x8 px, got {self.width_px}x{self.height_px}")
        if not (math.isfinite(self.f_v_px) and self.f_v_px > 0):
            raise ConfigError(f"f_v_px must be finite and > 0, got {self.f_v_px}")
        if not math.isfinite(self.v0_px) or not math.isfinite(self.height_m):
            raise ConfigError(f"v0_px and height_m must be finite, got {self.v0_px}, {self.height_m}")
        if self.direction not in (1, -1):
            raise ConfigError(f"direction must be +1 or -1, got {self.direction}")

    @property
    def f_h_px(self) -> float:
        """Horizontal focal length: the cylinder radius in pixels, width / 2 pi."""
        return self.width_px / TWO_PI

    # -- horizontal: circular projection ---------------------------------------------------------
    @overload
    def bearing_from_col(self, u: float) -> float: ...
    @overload
    def bearing_from_col(self, u: FloatArray) -> FloatArray: ...
    def bearing_from_col(self, u: FloatArray | float) -> FloatArray | float:
        """Sensor-frame bearing (rad, wrapped to [-pi, pi)) of a (fractional) column."""
        b = self.bearing0_rad + self.direction * np.asarray(u, dtype=np.float64) / self.f_h_px
        return _out(wrap_angle(b), u)

    @overload
    def col_from_bearing(self, bearing_rad: float) -> float: ...
    @overload
    def col_from_bearing(self, bearing_rad: FloatArray) -> FloatArray: ...
    def col_from_bearing(self, bearing_rad: FloatArray | float) -> FloatArray | float:
        """Column in [0, width) at which a sensor-frame bearing is imaged."""
        d = self.direction * (np.asarray(bearing_rad, dtype=np.float64) - self.bearing0_rad)
        u = np.mod(d * self.f_h_px, self.width_px)
        u = np.where(u >= self.width_px, 0.0, u)  # float rounding of mod for tiny negatives
        return _out(u, bearing_rad)

    # -- vertical: linear perspective -------------------------------------------------------------
    @overload
    def elevation_from_row(self, v: float) -> float: ...
    @overload
    def elevation_from_row(self, v: FloatArray) -> FloatArray: ...
    def elevation_from_row(self, v: FloatArray | float) -> FloatArray | float:
        """Elevation (rad) above the horizontal plane: tan eps = (v0 - v) / f_v."""
        e = np.arctan((self.v0_px - np.asarray(v, dtype=np.float64)) / self.f_v_px)
        return _out(e, v)

    @overload
    def row_from_elevation(self, elevation_rad: float) -> float: ...
    @overload
    def row_from_elevation(self, elevation_rad: FloatArray) -> FloatArray: ...
    def row_from_elevation(self, elevation_rad: FloatArray | float) -> FloatArray | float:
        """Row at which an elevation is imaged: v = v0 - f_v tan eps."""
        v = self.v0_px - self.f_v_px * np.tan(np.asarray(elevation_rad, dtype=np.float64))
        return _out(v, elevation_rad)

    def project(self, xyz_sensor: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Project points (N, 3) or (3,) of the sensor frame (z = height above floor) to (u, v).

        Points on the camera's vertical axis (rho = 0) get NaN.
        """
        p = np.asarray(xyz_sensor, dtype=np.float64)
        x, y, z = p[..., 0], p[..., 1], p[..., 2]
        rho = np.hypot(x, y)
        u = np.asarray(self.col_from_bearing(np.asarray(np.arctan2(y, x))), dtype=np.float64)
        with np.errstate(divide="ignore", invalid="ignore"):
            v = self.v0_px - self.f_v_px * (z - self.height_m) / rho
        bad = rho <= 0
        return np.where(bad, np.nan, u), np.where(bad, np.nan, v)

    @overload
    def floor_distance(self, v_foot: float) -> float: ...
    @overload
    def floor_distance(self, v_foot: FloatArray) -> FloatArray: ...
    def floor_distance(self, v_foot: FloatArray | float) -> FloatArray | float:
        """Horizontal distance (m) of a floor point imaged at row ``v_foot``: f_v H_c / (v_foot - v0).

        Rows at or above the horizon see no floor: the result is +inf there.
        """
        dv = np.asarray(v_foot, dtype=np.float64) - self.v0_px
        with np.errstate(divide="ignore"):
            rho = np.where(dv > 0, self.f_v_px * self.height_m / np.where(dv > 0, dv, 1.0), np.inf)
        return _out(rho, v_foot)

    @overload
    def point_height(self, v: float, distance_m: float) -> float: ...
    @overload
    def point_height(self, v: FloatArray, distance_m: FloatArray | float) -> FloatArray: ...
    def point_height(self, v: FloatArray | float, distance_m: FloatArray | float) -> FloatArray | float:
        """Height above the floor (m) of a point imaged at row ``v`` at horizontal distance ``distance_m``."""
        z = self.height_m + np.asarray(distance_m, dtype=np.float64) * (self.v0_px - np.asarray(v)) / self.f_v_px
        return _out(z, v)

    def metric_width(self, width_px: float, distance_m: float) -> float:
        """Physical width (m) of an object spanning ``width_px`` columns at ``distance_m``: 2 rho tan(w / 2 f_h)."""
        return 2.0 * distance_m * math.tan(width_px / (2.0 * self.f_h_px))

    # -- wire model --------------------------------------------------------------------------------
    def to_model(self) -> PanoramicModel:
        """The wire form (``schema.PanoramicModel``); the bearing offset and height travel in ``Pose``."""
        return PanoramicModel(
            width_px=int(self.width_px),
            height_px=int(self.height_px),
            f_v_px=float(self.f_v_px),
            v0_px=float(self.v0_px),
            direction=int(self.direction),
        )

    @classmethod
    def from_model(cls, model: PanoramicModel, height_m: float) -> CylindricalCamera:
        """Build from the wire form and the camera height (``Pose.z_m``); column 0 is bearing 0."""
        return cls(
            width_px=model.width_px,
            height_px=model.height_px,
            f_v_px=model.f_v_px,
            v0_px=model.v0_px,
            height_m=height_m,
            direction=model.direction,
        )


@dataclass(frozen=True, slots=True)
class CylindricalCalibration:
    """Result of :func:`calibrate_cylindrical`."""

    camera: CylindricalCamera
    residuals_px: FloatArray
    """(N, 2) reprojection residuals (du, dv), measured minus predicted, du wrapped to +-W/2."""
    rms_px: float
    """sqrt(mean(du^2 + dv^2))."""


def calibrate_cylindrical(
    points_xyz_sensor: npt.ArrayLike,
    pixels_uv: npt.ArrayLike,
    width_px: int,
    height_px: int,
) -> CylindricalCalibration:
    """Estimate f_v, v0, H_c (and the bearing offset, direction) from >= 3 known scene points (Step 3).

    Vertically, v_i = v0 - f_v Z_i / rho_i + (f_v H_c) / rho_i is linear in
    (v0, f_v, f_v H_c): one least-squares solve. Horizontally f_h = W / 2 pi is
    fixed by the unwarping; the column offset is the circular mean of
    (bearing_i - s u_i / f_h) for the direction s that fits best.

    Args:
        points_xyz_sensor: (N, 3) scene points in the sensor frame, z = height above the floor.
        pixels_uv: (N, 2) where they are imaged in the panorama.
        width_px: panorama width.
        height_px: panorama height.

    Raises:
        CalibrationError: fewer than 3 points, shapes disagree, points on the axis or
            all at one (Z/rho, 1/rho) (degenerate), or a non-physical solution (f_v <= 0).
    """
    p = np.asarray(points_xyz_sensor, dtype=np.float64)
    uv = np.asarray(pixels_uv, dtype=np.float64)
    if p.shape[1:] != (3,) or uv.shape != (len(p), 2):
        raise CalibrationError(f"expected points (N,3) and pixels (N,2), got {p.shape} and {uv.shape}")
    n = p.shape[0]
    if n < CALIB_UNKNOWNS:
        raise CalibrationError(f"calibration needs >= 3 known points, got {n}")
    if not (np.all(np.isfinite(p)) and np.all(np.isfinite(uv))):
        raise CalibrationError("calibration points and pixels must be finite")
    rho = np.hypot(p[:, 0], p[:, 1])
    if np.any(rho <= ON_AXIS_M):
        raise CalibrationError("a calibration point lies on the camera axis (rho = 0)")
    a = np.column_stack([np.ones(n), -p[:, 2] / rho, 1.0 / rho])
    sol, _, rank, _ = np.linalg.lstsq(a, uv[:, 1], rcond=None)
    if rank < CALIB_UNKNOWNS:
        raise CalibrationError(f"degenerate calibration points: rank {rank} < 3 (vary distance and height)")
    v0, f_v, fvh = (float(s) for s in sol)
    if not f_v > 0:
        raise CalibrationError(f"calibration gave a non-physical vertical focal length f_v = {f_v:.4g} px")
    f_h = width_px / TWO_PI
    bearings = np.arctan2(p[:, 1], p[:, 0])
    best: tuple[float, int, float] | None = None
    for direction in (1, -1):
        offs = bearings - direction * uv[:, 0] / f_h
        b0 = math.atan2(float(np.mean(np.sin(offs))), float(np.mean(np.cos(offs))))
        cost = float(np.sum(wrap_angle(offs - b0) ** 2))
        if best is None or cost < best[0]:
            best = (cost, direction, b0)
    assert best is not None
    camera = CylindricalCamera(
        width_px=width_px,
        height_px=height_px,
        f_v_px=f_v,
        v0_px=v0,
        height_m=fvh / f_v,
        direction=best[1],
        bearing0_rad=best[2],
    )
    u_hat, v_hat = camera.project(p)
    du = (uv[:, 0] - u_hat + width_px / 2.0) % width_px - width_px / 2.0
    res = np.column_stack([du, uv[:, 1] - v_hat])
    rms = float(np.sqrt(np.mean(np.sum(res**2, axis=1))))
    return CylindricalCalibration(camera=camera, residuals_px=res, rms_px=rms)
