"""The room: nobody stands outside it, nobody walks through its walls.

``[planner] room`` (``[x_min, y_min, x_max, y_max]``) bounds the floor. Near-colinear cameras put fixes far along
the ray (a 0.2 deg bearing error moves the fix metres there): a fix or a new person further than
``match.room_margin_m`` outside the room is refused, and a track predicted through a wall (a velocity built from
such fixes) is brought back to it without its velocity into the wall.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from resource_manager.track import TrackRecord

__all__ = ["Room"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class Room:
    x_min: float
    y_min: float
    x_max: float
    y_max: float
    margin_m: float = 0.5

    @staticmethod
    def of(bounds: list[float], margin_m: float) -> Room | None:
        """The room of ``[planner] room``, or None when it is not given."""
        return Room(bounds[0], bounds[1], bounds[2], bounds[3], margin_m) if len(bounds) == 4 else None

    def holds(self, xy: FloatArray) -> bool:
        """Whether a floor position can be someone's: inside the room grown by the margin."""
        x, y, m = float(xy[0]), float(xy[1]), self.margin_m
        return self.x_min - m <= x <= self.x_max + m and self.y_min - m <= y <= self.y_max + m

    def stop_at_walls(self, tr: TrackRecord) -> None:
        """Bring a predicted track that crossed a wall back to it, without its velocity through the wall."""
        for axis, lo, hi in ((0, self.x_min, self.x_max), (1, self.y_min, self.y_max)):
            x = float(tr.x[axis])
            if x < lo or x > hi:
                tr.x[axis] = min(max(x, lo), hi)
                v = float(tr.x[2 + axis])
                if (x < lo and v < 0) or (x > hi and v > 0):
                    tr.x[2 + axis] = 0.0
