"""The simulated PTZ head: slews at bounded rates, so a command takes visible time.

It implements the node's PTZ driver interface (:class:`sensor_node.ptz.PtzDriver`, by shape): the
node commands it, and the simulated camera renders from wherever it points at capture time.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable

from common.angles import angle_diff, wrap_angle
from common.frames import PtzPose

__all__ = ["SimulatedPtz"]


class SimulatedPtz:
    """A simulated head: slews at ``pan_rate``/``tilt_rate`` (rad/s) and zooms at ``zoom_rate`` (x/s).

    Args:
        pan_rad, tilt_rad, zoom: initial pose.
        clock: the node's clock (Unix ns); commands take effect from when they arrive.
        tilt_limit_rad: |tilt| is clamped below this.
        zoom_range: (min, max) zoom.
    """

    def __init__(
        self,
        pan_rad: float,
        tilt_rad: float,
        zoom: float,
        clock: Callable[[], int],
        *,
        pan_rate: float = math.radians(120.0),
        tilt_rate: float = math.radians(90.0),
        zoom_rate: float = 4.0,
        tilt_limit_rad: float = math.radians(80.0),
        zoom_range: tuple[float, float] = (1.0, 30.0),
    ) -> None:
        self._lock = threading.Lock()
        self.pan_rate, self.tilt_rate, self.zoom_rate = pan_rate, tilt_rate, zoom_rate
        self.tilt_limit_rad = tilt_limit_rad
        self.zoom_range = zoom_range
        self._start = PtzPose(wrap_angle(pan_rad), self._clamp_tilt(tilt_rad), self._clamp_zoom(zoom))
        self._target = self._start
        self._clock = clock
        self._t0_ns = clock()
        self.commands = 0

    def _clamp_tilt(self, t: float) -> float:
        return max(-self.tilt_limit_rad, min(self.tilt_limit_rad, t))

    def _clamp_zoom(self, z: float) -> float:
        return max(self.zoom_range[0], min(self.zoom_range[1], z))

    def _at(self, now_ns: int) -> PtzPose:
        dt = max(0.0, (now_ns - self._t0_ns) / 1e9)
        s, g = self._start, self._target
        dpan = angle_diff(g.pan_rad, s.pan_rad)
        dtilt = g.tilt_rad - s.tilt_rad
        dzoom = g.zoom - s.zoom

        def step(d: float, rate: float) -> tuple[float, bool]:
            m = rate * dt
            return (d, False) if abs(d) <= m else (math.copysign(m, d), True)

        p, mp = step(dpan, self.pan_rate)
        t, mt = step(dtilt, self.tilt_rate)
        z, mz = step(dzoom, self.zoom_rate)
        return PtzPose(wrap_angle(s.pan_rad + p), s.tilt_rad + t, s.zoom + z, mp or mt or mz)

    def command(self, pan_rad: float, tilt_rad: float, zoom: float) -> None:
        now = self._clock()
        with self._lock:
            cur = self._at(now)
            self._start = PtzPose(cur.pan_rad, cur.tilt_rad, cur.zoom)
            self._target = PtzPose(wrap_angle(pan_rad), self._clamp_tilt(tilt_rad), self._clamp_zoom(zoom))
            self._t0_ns = now
            self.commands += 1

    def pose(self, now_ns: int) -> PtzPose:
        with self._lock:
            return self._at(now_ns)
