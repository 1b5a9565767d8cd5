"""Perspective and PTZ cameras: K, lens distortion and pose, x_cam = R x_world + t (metres).

World frame: the floor plane, z up. Camera frame (OpenCV): x right, y down, z
forward. The distortion model is OpenCV's (k1 k2 p1 p2 [k3 [k4 k5 k6 [s1 s2 s3
s4 [tau_x tau_y]]]]); the tilted-sensor terms tau must be zero.

Azimuths are counter-clockwise from world +x; elevations are above the
horizontal plane through the optical centre (docs/geometry.md section 5).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from common.arrays import FloatArray
from common.errors import ConfigError
from common.schema import PinholeModel

__all__ = ["PinholeCamera", "PtzCamera", "rotation_from_rvec"]

NO_ROTATION_RAD = 1e-15
"""An axis-angle vector shorter than this is no rotation."""
K22_TOLERANCE = 1e-9
"""K[2, 2] must be 1 within this."""
UNDISTORT_TOLERANCE = 1e-12
"""Undistortion's Newton iteration stops below this residual (normalised coordinates); a Jacobian
determinant below it is clamped to it."""
IN_FRONT_M = 1e-12
"""A point is in front of the camera when its camera-frame z exceeds this."""
IMAGE_SIZE_VALUES = 2
"""``image_size`` is [width, height]."""
_TILT_TERMS = slice(12, 14)
"""OpenCV's tilted-sensor coefficients (tau_x, tau_y) in a 14-term distortion vector."""

_DIST_LENGTHS = (0, 4, 5, 8, 12, 14)


def rotation_from_rvec(rvec: npt.ArrayLike) -> FloatArray:
    """Rodrigues: rotation matrix of an axis-angle vector (as ``cv2.Rodrigues``)."""
    w = np.asarray(rvec, dtype=np.float64).reshape(3)
    theta = float(np.linalg.norm(w))
    if theta < NO_ROTATION_RAD:
        return np.eye(3)
    k = w / theta
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(theta) * kx + (1.0 - math.cos(theta)) * (kx @ kx)


def _matrix(d: dict[str, Any], key: str, shape: tuple[int, ...], source: str) -> FloatArray:
    if key not in d:
        raise ConfigError(f"{source}: missing key {key!r}")
    try:
        a = np.asarray(d[key], dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise ConfigError(f"{source}: {key} must be numeric, got {d[key]!r}") from err
    if a.size != math.prod(shape):
        raise ConfigError(f"{source}: {key} must have shape {shape}, got {a.shape}")
    a = a.reshape(shape)
    if not np.all(np.isfinite(a)):
        raise ConfigError(f"{source}: {key} must be finite")
    return a


def _rq3(m: FloatArray) -> tuple[FloatArray, FloatArray]:
    """RQ decomposition of a 3x3 matrix: m = upper-triangular @ orthogonal."""
    p = np.flipud(np.eye(3))
    q, r = np.linalg.qr((p @ m).T)
    return p @ r.T @ p, p @ q.T


@dataclass(frozen=True, slots=True, eq=False)
class PinholeCamera:
    """A calibrated perspective camera. Arrays are read-only copies."""

    k: FloatArray
    """(3, 3) intrinsics."""
    dist: FloatArray
    """(n,) OpenCV distortion coefficients, n in {0, 4, 5, 8, 12, 14}."""
    r: FloatArray
    """(3, 3) world-to-camera rotation."""
    t: FloatArray
    """(3,) translation (m): x_cam = R x_world + t."""
    width_px: int
    height_px: int
    _coef: tuple[float, ...] = field(init=False, repr=False, compare=False)
    """The twelve distortion coefficients as floats (absent ones 0), read once: the lens model runs per pixel."""

    def __post_init__(self) -> None:
        for name, shape in (("k", (3, 3)), ("r", (3, 3)), ("t", (3,))):
            a = np.array(getattr(self, name), dtype=np.float64)
            if a.shape != shape or not np.all(np.isfinite(a)):
                raise ConfigError(f"pinhole {name} must be finite with shape {shape}, got {a.shape}")
            a.setflags(write=False)
            object.__setattr__(self, name, a)
        dist = np.array(self.dist, dtype=np.float64).ravel()
        if dist.size not in _DIST_LENGTHS or not np.all(np.isfinite(dist)):
            raise ConfigError(f"pinhole dist must have one of {_DIST_LENGTHS} finite values, got {dist.size}")
        if dist.size == max(_DIST_LENGTHS) and np.any(dist[_TILT_TERMS] != 0):
            raise ConfigError("pinhole dist: tilted-sensor terms (tau_x, tau_y) are not supported, must be 0")
        dist.setflags(write=False)
        object.__setattr__(self, "dist", dist)
        coef = [0.0] * 12
        coef[: min(dist.size, 12)] = [float(c) for c in dist[:12]]
        object.__setattr__(self, "_coef", tuple(coef))
        if not (self.k[0, 0] > 0 and self.k[1, 1] > 0 and abs(self.k[2, 2] - 1) < K22_TOLERANCE):
            raise ConfigError(f"pinhole K must have fx, fy > 0 and K[2,2] = 1, got {self.k.tolist()}")
        if not np.allclose(self.r @ self.r.T, np.eye(3), atol=1e-4) or np.linalg.det(self.r) < 0:
            raise ConfigError("pinhole R must be a rotation (orthonormal, det +1)")
        if self.width_px < 1 or self.height_px < 1:
            raise ConfigError(f"pinhole image size must be positive, got {self.width_px}x{self.height_px}")

    # -- construction ------------------------------------------------------------------------------
    @classmethod
    def from_calibration(cls, d: dict[str, Any], source: str) -> PinholeCamera:
        """Parse a calibration JSON object; ``source`` names it in errors.

        Accepted forms (metres)::

            {"model": "pinhole", "image_size": [w, h], "K": 3x3, "dist": [...], "R": 3x3, "t": [3]}
            {"model": "pinhole", "image_size": [w, h], "K": ..., "rvec": [3], "t": [3]}   (Rodrigues)
            {"model": "pinhole", "image_size": [w, h], "P": 3x4}   (decomposed as K [R | t], no distortion)

        Raises:
            ConfigError: not a dict, wrong model, missing/ill-shaped/non-finite entries, or a singular P.
        """
        if not isinstance(d, dict):
            raise ConfigError(f"{source}: expected a JSON object, got {type(d).__name__}")
        if d.get("model", "pinhole") != "pinhole":
            raise ConfigError(f"{source}: model must be 'pinhole', got {d.get('model')!r}")
        size = d.get("image_size")
        if (
            not isinstance(size, list | tuple)
            or len(size) != IMAGE_SIZE_VALUES
            or not all(isinstance(s, int) and not isinstance(s, bool) and s > 0 for s in size)
        ):
            raise ConfigError(f"{source}: image_size must be [width, height] positive integers, got {size!r}")
        w, h = int(size[0]), int(size[1])
        try:
            if "P" in d:
                return cls._from_projection(_matrix(d, "P", (3, 4), source), w, h)
            k = _matrix(d, "K", (3, 3), source)
            dist_raw = d.get("dist", [])
            dist = np.asarray(dist_raw if dist_raw is not None else [], dtype=np.float64).ravel()
            if "rvec" in d and "R" not in d:
                rot = rotation_from_rvec(_matrix(d, "rvec", (3,), source))
            else:
                rot = _matrix(d, "R", (3, 3), source)
            return cls(k=k, dist=dist, r=rot, t=_matrix(d, "t", (3,), source), width_px=w, height_px=h)
        except ConfigError as err:
            msg = str(err)
            if msg.startswith(f"{source}:"):
                raise
            raise ConfigError(f"{source}: {msg}") from err
        except (TypeError, ValueError) as err:
            raise ConfigError(f"{source}: invalid pinhole calibration: {err}") from err

    @classmethod
    def _from_projection(cls, p: FloatArray, width_px: int, height_px: int) -> PinholeCamera:
        m = p[:, :3]
        det = float(np.linalg.det(m))
        if abs(det) < 1e-12 * max(1.0, float(np.abs(m).max()) ** 3):
            raise ConfigError("P's left 3x3 block is singular")
        if det < 0:  # P is defined up to scale; choose the sign that makes R a proper rotation
            p = -p
            m = -m
        k, rot = _rq3(m)
        s = np.diag(np.sign(np.diag(k)))  # make K's diagonal positive; s @ s = I
        k, rot = k @ s, s @ rot
        t = np.linalg.solve(k, p[:, 3])
        scale = k[2, 2]
        return cls(k=k / scale, dist=np.zeros(0), r=rot, t=t, width_px=width_px, height_px=height_px)

    @classmethod
    def from_model(cls, model: PinholeModel) -> PinholeCamera:
        """Build from the wire form."""
        return cls(
            k=np.asarray(model.k).reshape(3, 3),
            dist=np.asarray(model.dist, dtype=np.float64),
            r=np.asarray(model.r).reshape(3, 3),
            t=np.asarray(model.t_m, dtype=np.float64),
            width_px=model.width_px,
            height_px=model.height_px,
        )

    def to_model(self) -> PinholeModel:
        """The wire form (Python floats)."""
        return PinholeModel(
            width_px=int(self.width_px),
            height_px=int(self.height_px),
            k=[float(x) for x in self.k.ravel()],
            dist=[float(x) for x in self.dist],
            r=[float(x) for x in self.r.ravel()],
            t_m=[float(x) for x in self.t],
        )

    @property
    def center_world(self) -> FloatArray:
        """Optical centre in the world frame: -R^T t."""
        return np.asarray(-self.r.T @ self.t, dtype=np.float64)

    # -- distortion ----------------------------------------------------------------------------------
    def _distort(self, x: FloatArray, y: FloatArray) -> tuple[FloatArray, FloatArray]:
        """OpenCV forward distortion of normalised coordinates."""
        k1, k2, p1, p2, k3, k4, k5, k6, s1, s2, s3, s4 = self._coef
        r2 = x * x + y * y
        radial = (1 + r2 * (k1 + r2 * (k2 + r2 * k3))) / (1 + r2 * (k4 + r2 * (k5 + r2 * k6)))
        xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x) + s1 * r2 + s2 * r2 * r2
        yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y + s3 * r2 + s4 * r2 * r2
        return xd, yd

    def _distort_jacobian(
        self, x: FloatArray, y: FloatArray
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
        """:meth:`_distort` and its Jacobian: (xd, yd, dxd/dx, dxd/dy, dyd/dx, dyd/dy)."""
        k1, k2, p1, p2, k3, k4, k5, k6, s1, s2, s3, s4 = self._coef
        r2 = x * x + y * y
        a = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
        b = 1 + r2 * (k4 + r2 * (k5 + r2 * k6))
        radial = a / b
        # d radial / d r2, and d r2 / dx = 2x, d r2 / dy = 2y.
        d_radial = ((k1 + r2 * (2 * k2 + 3 * k3 * r2)) * b - a * (k4 + r2 * (2 * k5 + 3 * k6 * r2))) / (b * b)
        xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x) + s1 * r2 + s2 * r2 * r2
        yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y + s3 * r2 + s4 * r2 * r2
        gx = 2 * d_radial * x  # d radial / dx
        gy = 2 * d_radial * y
        sx = 2 * (s1 + 2 * s2 * r2)  # d (s1 r2 + s2 r2^2) / d r2, times 2
        sy = 2 * (s3 + 2 * s4 * r2)
        j11 = radial + x * gx + 2 * p1 * y + 6 * p2 * x + sx * x
        j12 = x * gy + 2 * p1 * x + 2 * p2 * y + sx * y
        j21 = y * gx + 2 * p1 * x + 2 * p2 * y + sy * x
        j22 = radial + y * gy + 6 * p1 * y + 2 * p2 * x + sy * y
        return xd, yd, j11, j12, j21, j22

    def _normalised(self, uv: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Undistorted normalised coordinates (x, y) of pixels (N, 2)."""
        p = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
        k = self.k
        yd = (p[:, 1] - k[1, 2]) / k[1, 1]
        xd = (p[:, 0] - k[0, 2] - k[0, 1] * yd) / k[0, 0]
        if not any(self._coef):
            return xd, yd
        # Newton iterations on distort(x, y) = (xd, yd); converges in a few steps.
        x, y = xd.copy(), yd.copy()
        for _ in range(20):
            fx, fy, j11, j12, j21, j22 = self._distort_jacobian(x, y)
            ex, ey = fx - xd, fy - yd
            if float(np.max(np.abs(ex) + np.abs(ey))) < UNDISTORT_TOLERANCE:
                break
            det = j11 * j22 - j12 * j21
            det = np.where(np.abs(det) < UNDISTORT_TOLERANCE, UNDISTORT_TOLERANCE, det)
            x = x - (j22 * ex - j12 * ey) / det
            y = y - (-j21 * ex + j11 * ey) / det
        return x, y

    def undistort_points(self, uv: npt.ArrayLike) -> FloatArray:
        """Pixels (N, 2) as an ideal (distortion-free) camera with the same K would image them."""
        x, y = self._normalised(uv)
        k = self.k
        return np.column_stack([k[0, 0] * x + k[0, 1] * y + k[0, 2], k[1, 1] * y + k[1, 2]])

    # -- projection ----------------------------------------------------------------------------------
    def project(self, xyz_world: npt.ArrayLike) -> tuple[FloatArray, npt.NDArray[np.bool_]]:
        """World points (N, 3) -> pixels (N, 2) and in_front (N,) (camera z > 0)."""
        p = np.asarray(xyz_world, dtype=np.float64).reshape(-1, 3)
        c = p @ self.r.T + self.t
        in_front = c[:, 2] > IN_FRONT_M
        with np.errstate(divide="ignore", invalid="ignore"):
            z = np.where(in_front, c[:, 2], np.nan)
            xd, yd = self._distort(c[:, 0] / z, c[:, 1] / z)
        k = self.k
        uv = np.column_stack([k[0, 0] * xd + k[0, 1] * yd + k[0, 2], k[1, 1] * yd + k[1, 2]])
        return uv, in_front

    def ray_world(self, uv: npt.ArrayLike) -> FloatArray:
        """Unit world directions (N, 3) of the rays through pixels (N, 2)."""
        x, y = self._normalised(uv)
        d_cam = np.column_stack([x, y, np.ones_like(x)])
        d = d_cam @ self.r  # R^T d for each row
        return np.asarray(d / np.linalg.norm(d, axis=1, keepdims=True), dtype=np.float64)

    def bearing_elevation(self, uv: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
        """World azimuth (CCW from +x) and elevation (above horizontal) of the rays through pixels (N, 2)."""
        d = self.ray_world(uv)
        return np.arctan2(d[:, 1], d[:, 0]), np.arctan2(d[:, 2], np.hypot(d[:, 0], d[:, 1]))


@dataclass(frozen=True, slots=True)
class PtzCamera:
    """A pan-tilt-zoom head at a surveyed position; zoom scales the focal length of the zoom-1 field of view."""

    x_m: float
    y_m: float
    z_m: float
    """Height of the optical centre above the floor."""
    width_px: int
    height_px: int
    hfov_rad: float
    """Horizontal field of view at zoom 1."""
    pan_rad: float = 0.0
    """World azimuth of the optical axis (counter-clockwise from +x)."""
    tilt_rad: float = 0.0
    """Elevation of the optical axis, > 0 up."""
    zoom: float = 1.0

    def __post_init__(self) -> None:
        if not 0 < self.hfov_rad < math.pi:
            raise ConfigError(f"PTZ hfov_rad must be in (0, pi), got {self.hfov_rad}")
        if not self.zoom > 0:
            raise ConfigError(f"PTZ zoom must be > 0, got {self.zoom}")
        if not abs(self.tilt_rad) < math.pi / 2:
            raise ConfigError(f"PTZ tilt_rad must be in (-pi/2, pi/2), got {self.tilt_rad}")

    def with_state(self, pan_rad: float, tilt_rad: float, zoom: float) -> PtzCamera:
        """The same head pointed elsewhere."""
        return PtzCamera(
            self.x_m, self.y_m, self.z_m, self.width_px, self.height_px, self.hfov_rad, pan_rad, tilt_rad, zoom
        )

    @property
    def focal_px(self) -> float:
        """Focal length at the current zoom: zoom * (W/2) / tan(hfov/2)."""
        return self.zoom * (self.width_px / 2.0) / math.tan(self.hfov_rad / 2.0)

    def pinhole(self) -> PinholeCamera:
        """The distortion-free perspective camera of the current state."""
        f = self.focal_px
        k = np.array([[f, 0.0, (self.width_px - 1) / 2.0], [0.0, f, (self.height_px - 1) / 2.0], [0.0, 0.0, 1.0]])
        cp, sp = math.cos(self.pan_rad), math.sin(self.pan_rad)
        ct, st = math.cos(self.tilt_rad), math.sin(self.tilt_rad)
        fwd = np.array([ct * cp, ct * sp, st])
        right = np.array([sp, -cp, 0.0])
        down = np.cross(fwd, right)
        rot = np.vstack([right, down, fwd])
        center = np.array([self.x_m, self.y_m, self.z_m])
        return PinholeCamera(
            k=k, dist=np.zeros(0), r=rot, t=-rot @ center, width_px=self.width_px, height_px=self.height_px
        )
