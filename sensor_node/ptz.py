"""PTZ heads: the driver interface the node commands, and the head's camera model.

The node receives :class:`~common.schema.PtzCommand` (pan = world azimuth of
the optical axis, tilt > 0 up, zoom), hands it to its driver, and publishes
:class:`~common.schema.PtzState` when the head's pose changes. A head (ONVIF,
Pelco-D, VISCA, ..., or the simulator's) plugs in by implementing
:class:`PtzDriver`; :class:`PtzHead` pairs it with the camera mounted on it, so
the pipeline and the SensorInfo follow the pose the head reports.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

from common.cameras import PinholeCamera, PtzCamera
from common.frames import PtzPose
from common.schema import PinholeModel

__all__ = ["PtzDriver", "PtzHead"]


class PtzDriver(Protocol):
    """What the node needs from a PTZ head."""

    def command(self, pan_rad: float, tilt_rad: float, zoom: float) -> None:
        """Start moving towards a pose (returns at once)."""
        ...

    def pose(self, now_ns: int) -> PtzPose:
        """Where the head points at ``now_ns`` (node clock)."""
        ...


@dataclass(frozen=True, slots=True)
class PtzHead:
    """A PTZ camera: the driver that moves the head, and the camera it carries."""

    driver: PtzDriver
    base: PtzCamera
    """The camera at the head's surveyed position; its pan, tilt and zoom are replaced by the head's pose."""

    def camera(self, pose: PtzPose) -> PinholeCamera:
        """The pinhole camera of the head in ``pose``."""
        return self.base.with_state(pose.pan_rad, pose.tilt_rad, pose.zoom).pinhole()

    def model(self, pose: PtzPose) -> PinholeModel:
        """The wire model (SensorInfo) of the head in ``pose``."""
        return self.camera(pose).to_model()
