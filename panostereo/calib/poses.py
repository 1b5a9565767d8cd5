"""A camera's pose as the refinement sees it, and the few numbers that move it.

Frames: *world* is the floor plane, z up, metres. A camera's *own frame* is the frame its rays are measured in:
a pinhole camera's OpenCV frame (x right, y down, z forward), or, for a *level* camera (panoramic, PTZ head),
its sensor frame (x along bearing 0, z up). ``rotation`` maps world directions into the own frame
(``x_cam = R (x_world - centre)``), as a pinhole calibration's R does.

Parameters: a pinhole camera turns freely, so it has six (a rotation vector applied in its own frame, then the
centre's shift in metres); a level camera only turns about the vertical, so it has four (the yaw's change, then
the centre's shift). Zero parameters are the starting pose.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.spatial.transform import Rotation

from common.arrays import FloatArray
from common.pinhole import rotation_from_rvec

__all__ = ["CameraPose", "pose_change", "pose_offset", "rotation_z"]

PINHOLE_PARAMS = 6
LEVEL_PARAMS = 4


def rotation_z(angle_rad: float) -> FloatArray:
    """Rotation about the world's vertical by ``angle_rad`` (counter-clockwise)."""
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@dataclass(frozen=True, slots=True, eq=False)
class CameraPose:
    """Where a camera is and how it is turned."""

    rotation: FloatArray
    """(3, 3) world -> own frame."""
    centre_m: FloatArray
    """(3,) optical centre in the world."""
    level: bool
    """True: a level camera (panoramic or PTZ head), which only turns about the vertical."""

    @classmethod
    def from_yaw(cls, x_m: float, y_m: float, z_m: float, yaw_rad: float) -> CameraPose:
        """A level camera whose sensor x axis points at world azimuth ``yaw_rad``."""
        return cls(rotation_z(yaw_rad).T, np.array([x_m, y_m, z_m], dtype=np.float64), level=True)

    @property
    def yaw_rad(self) -> float:
        """World azimuth of the own frame's x axis (level cameras)."""
        return math.atan2(float(self.rotation[0, 1]), float(self.rotation[0, 0]))

    @property
    def n_params(self) -> int:
        return LEVEL_PARAMS if self.level else PINHOLE_PARAMS

    @property
    def t_m(self) -> FloatArray:
        """The pinhole translation: x_cam = R x_world + t."""
        return np.asarray(-self.rotation @ self.centre_m, dtype=np.float64)

    def moved(self, params: npt.ArrayLike) -> CameraPose:
        """This pose changed by ``params`` (see the module docstring)."""
        p = np.asarray(params, dtype=np.float64)
        if self.level:
            rot = self.rotation @ rotation_z(-float(p[0]))
            return CameraPose(rot, self.centre_m + p[1:4], level=True)
        return CameraPose(rotation_from_rvec(p[:3]) @ self.rotation, self.centre_m + p[3:6], level=False)

    def turned_moved(self, axis_angle: npt.ArrayLike, shift_m: npt.ArrayLike) -> CameraPose:
        """This pose turned about its centre by a world-frame rotation vector and moved (a bump)."""
        turn = rotation_from_rvec(axis_angle)
        return CameraPose(self.rotation @ turn.T, self.centre_m + np.asarray(shift_m, dtype=np.float64), self.level)


def pose_change(a: CameraPose, b: CameraPose) -> tuple[float, float]:
    """How far ``b`` is from ``a``: the centres' distance (m) and the angle of the relative rotation (rad)."""
    dist = float(np.linalg.norm(b.centre_m - a.centre_m))
    rel = b.rotation @ a.rotation.T
    cos = (float(np.trace(rel)) - 1.0) / 2.0
    return dist, math.acos(max(-1.0, min(1.0, cos)))


def pose_offset(guess: CameraPose, rotation: FloatArray, centre_m: FloatArray) -> FloatArray:
    """The parameters that move ``guess`` to the pose (``rotation``, ``centre_m``): the inverse of
    :meth:`CameraPose.moved` (a level camera's yaw change wrapped to +-pi)."""
    shift = np.asarray(centre_m, dtype=np.float64) - guess.centre_m
    if guess.level:
        yaw = math.atan2(float(rotation[0, 1]), float(rotation[0, 0]))
        turn = math.remainder(yaw - guess.yaw_rad, math.tau)
        return np.concatenate([[turn], shift])
    rvec = Rotation.from_matrix(np.asarray(rotation) @ guess.rotation.T).as_rotvec()
    return np.concatenate([rvec, shift])
