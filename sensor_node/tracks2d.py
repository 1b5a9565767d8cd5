"""Stage 6: short 2D tracks, so each blob keeps a node-local id across frames.

The manager interpolates one camera's blob bearings between the two frames
that bracket its fusion instant (docs/zenoh.md §8.3); for that it must know which
blob of frame k+1 is which blob of frame k. A constant-velocity nearest
neighbour is plenty at camera rates: people move a few pixels per frame.

Positions are 2-vectors (e.g. head column and row, or bearing and elevation);
the first coordinate may be periodic (a panorama's columns, bearings).
Assignment is greedy by distance within ``gate`` (the paper's "greedy"
spirit); a track survives ``max_missed`` frames without a blob.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Tracker2D"]


@dataclass(slots=True)
class _Track:
    local_id: int
    x: float
    y: float
    vx: float = 0.0
    vy: float = 0.0
    missed: int = 0
    hits: int = 1
    solo_hits: int = 1
    """Frames whose blob stood alone (not cut from a group by its predicted position)."""


class Tracker2D:
    """Greedy constant-velocity nearest-neighbour tracker giving stable local ids.

    Args:
        gate: largest distance between a track's predicted position and a blob to continue it.
        max_missed: frames a track survives unmatched.
        period: period of the first coordinate (panorama width or 2 pi); 0 for none.
    """

    def __init__(self, gate: float, max_missed: int = 5, period: float = 0.0) -> None:
        self.gate = gate
        self.max_missed = max_missed
        self.period = period
        self._tracks: list[_Track] = []
        self._next_id = 0

    def __len__(self) -> int:
        return len(self._tracks)

    def predicted(self, min_hits: int, max_missed: int = 0) -> list[tuple[float, float]]:
        """Predicted next positions of the tracks with at least ``min_hits`` solo hits (frames whose blob
        stood alone), missed at most ``max_missed`` frames in a row (0: seen in the last frame)."""
        out = []
        for t in self._tracks:
            if t.missed <= max_missed and t.solo_hits >= min_hits:
                x = t.x + t.vx
                out.append((x % self.period if self.period > 0 else x, t.y + t.vy))
        return out

    def _dx(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        d = a - b
        if self.period > 0:
            d = (d + self.period / 2) % self.period - self.period / 2
        return d

    def _dx_one(self, a: float, b: float) -> float:
        """:meth:`_dx` of two numbers (plain floats: the same operations, without numpy's per-call cost)."""
        d = a - b
        if self.period > 0:
            d = (d + self.period / 2) % self.period - self.period / 2
        return d

    def update(self, positions: list[tuple[float, float]], cut: list[bool] | None = None) -> list[int]:
        """Assign a local id to each position of this frame (same order); unmatched ones get new ids.

        Args:
            positions: this frame's blob positions.
            cut: per position, True if its blob was cut from a group by the tracks' predictions (it does
                not count as a solo hit); None: none was.
        """
        ids = [-1] * len(positions)
        if self._tracks and positions:
            p = np.asarray(positions, dtype=np.float64)
            pred = np.array([(t.x + t.vx, t.y + t.vy) for t in self._tracks])
            dx = self._dx(p[:, 0][None, :], pred[:, 0][:, None])
            dy = p[:, 1][None, :] - pred[:, 1][:, None]
            dist = np.hypot(dx, dy)
            pairs = np.argwhere(dist <= self.gate)
            order = np.argsort(dist[pairs[:, 0], pairs[:, 1]], kind="stable")
            used_t: set[int] = set()
            for pair in pairs[order]:
                ti, di = int(pair[0]), int(pair[1])
                if ti in used_t or ids[di] >= 0:
                    continue
                used_t.add(ti)
                t = self._tracks[ti]
                x, y = positions[di]
                vx = self._dx_one(x, t.x)
                t.vx, t.vy = 0.5 * t.vx + 0.5 * vx, 0.5 * t.vy + 0.5 * (y - t.y)
                t.x, t.y, t.missed, t.hits = x, y, 0, t.hits + 1
                t.solo_hits += not (cut and cut[di])
                ids[di] = t.local_id
            for ti, t in enumerate(self._tracks):
                if ti not in used_t:
                    t.missed += 1
                    t.x, t.y = t.x + t.vx, t.y + t.vy
                    if self.period > 0:
                        t.x %= self.period
        else:
            for t in self._tracks:
                t.missed += 1
        self._tracks = [t for t in self._tracks if t.missed <= self.max_missed]
        for di, (x, y) in enumerate(positions):
            if ids[di] < 0:
                t = _Track(self._next_id, x, y, solo_hits=int(not (cut and cut[di])))
                self._next_id += 1
                self._tracks.append(t)
                ids[di] = t.local_id
        return ids
