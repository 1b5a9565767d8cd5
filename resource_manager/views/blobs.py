"""The blobs of one camera at the fusion instant, in world terms: what every manager stage works on."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from common.angles import angle_diff
from common.arrays import FloatArray

__all__ = ["ImageBounds", "ViewBlobs"]

MIN_DEPTH_M = 1e-6
"""A point must be at least this far in front of a perspective camera (m) to project into its picture."""


@dataclass(frozen=True, slots=True)
class ImageBounds:
    """Where a perspective camera's picture is: its ideal (distortion-free) projection and image size.

    Distortion is left out on purpose: a strong lens model folds far-off points back into the image, and the
    ideal projection of a point in view lies within a few pixels of the image rectangle anyway.
    """

    k: FloatArray
    """(3, 3) intrinsics."""
    r: FloatArray
    """(3, 3) world -> camera rotation."""
    t: FloatArray
    """(3,) world -> camera translation (m)."""
    width_px: int
    height_px: int

    def inside(self, xyz: FloatArray, margin_px: float = 0.0) -> npt.NDArray[np.bool_]:
        """(n,) whether world points (n, 3) project into the picture (in front of the camera)."""
        c = np.asarray(xyz, dtype=np.float64).reshape(-1, 3) @ self.r.T + self.t
        front = c[:, 2] > MIN_DEPTH_M
        z = np.where(front, c[:, 2], 1.0)
        u = self.k[0, 0] * c[:, 0] / z + self.k[0, 1] * c[:, 1] / z + self.k[0, 2]
        v = self.k[1, 1] * c[:, 1] / z + self.k[1, 2]
        m = margin_px
        return np.asarray(
            front & (u >= -m) & (u <= self.width_px + m) & (v >= -m) & (v <= self.height_px + m), dtype=bool
        )


@dataclass(frozen=True, slots=True)
class ViewBlobs:
    """The blobs of one camera at the fusion instant, in world terms."""

    sensor_id: str
    origin_xy: FloatArray
    """(2,) optical centre on the floor plane."""
    z_m: float
    """Height of the optical centre."""
    sigma_rad: float
    """1-sigma bearing error (the sensor's, plus its pose's yaw error)."""
    bearing_rad: FloatArray
    """(n,) world azimuths of the heads."""
    width_rad: FloatArray
    """(n,) angular widths."""
    top_elev_rad: FloatArray
    """(n,) elevations of the blob tops."""
    hist: FloatArray | None
    """(n, k) L1-normalised histograms, or None when the sensor sends none."""
    local_id: npt.NDArray[np.int64]
    """(n,) the node's 2D track ids."""
    hist_sqrt: FloatArray | None = None
    """Element-wise square roots of ``hist`` (for the Bhattacharyya coefficient), precomputed per view."""
    bottom_elev_rad: FloatArray | None = None
    """(n,) elevations of the blob bottoms (feet), NaN where the feet are not visible; None: unknown."""
    fov: tuple[float, float] | None = None
    """(world azimuth of the optical axis, half width) of a perspective camera; None: 360 deg (panoramic)."""
    mono_range_m: FloatArray | None = None
    """(n,) floor distance of each blob from its feet elevation (:mod:`~resource_manager.views.mono`), NaN where
    not observable; None: the camera gives none."""
    mono_sigma_m: FloatArray | None = None
    """(n,) 1-sigma of ``mono_range_m``."""
    top_cut: npt.NDArray[np.bool_] | None = None
    """(n,) blobs whose top touches the image's upper border (a person close to the camera): their head-top
    height is only a lower bound. None: none are."""
    sigma_xy_m: float = 0.0
    """1-sigma error of the camera's own floor position (mutual calibration; 0: surveyed)."""
    point_sigma_m: float = 0.0
    """Spread of the sensor's measured point around a person's floor position (0: not stated)."""
    period_s: float = 0.0
    """Frame period of the sensor (0: unknown): successive ticks between two frames see the same evidence."""
    image: ImageBounds | None = None
    """A perspective camera's projection, to tell whether a floor position is in its picture (None: panoramic)."""
    body_radius_m: float = 0.0
    """Radius of the camera's body (a robot, a post): a cylinder from the floor up to the camera, which hides what
    stands behind it from the other cameras (0: none)."""
    confidence: FloatArray | None = None
    """(n,) the node's confidence in each blob (a detector's score; None: all sure): a low one may update a track
    but never starts one."""

    def sees(self, azimuth_rad: float) -> bool:
        """Whether a world azimuth is inside this camera's horizontal field of view."""
        if self.fov is None:
            return True
        return abs(angle_diff(azimuth_rad, self.fov[0])) <= self.fov[1]

    @property
    def n(self) -> int:
        return int(self.bearing_rad.shape[0])
