"""Tracks published late, for those who can wait: each instant's tracks ``publish_lag_s`` after it, with the ids
the tracker settled on meanwhile.

A live tracker publishes a person only once it is sure of them (confirmed), and keeps an id it may later find
was someone else's: a new track that turns out to be a lost person back takes their old id only from then on.
Held back for a few seconds, the same tracks can be told better:

a person's first moments, while their track was still tentative, are published under the id it was confirmed with
(a new one, or the lost person's it took back), where it was placed well enough then; a tentative track that was
never confirmed is never published.

Pure: the tracker's snapshots in, instants of published tracks out; :func:`~resource_manager.serve.messages.lagged_set`
turns them into TrackSets.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass

from resource_manager.track.tracker import TrackSnapshot

__all__ = ["LaggedInstant", "LaggedTracks"]


@dataclass(frozen=True, slots=True)
class LaggedInstant:
    """One fused instant's tracks, due now, with the ids they are published under."""

    seq: int
    t_ns: int
    sensors_used: list[str]
    tracks: list[tuple[TrackSnapshot, str]]


@dataclass(slots=True)
class _Held:
    seq: int
    t_ns: int
    sensors_used: list[str]
    tracks: list[TrackSnapshot]


class LaggedTracks:
    """Instants held ``lag_ns`` before they are published (see the module docstring)."""

    def __init__(self, lag_ns: int) -> None:
        self.lag_ns = lag_ns
        self._held: deque[_Held] = deque()
        self._ids: dict[int, str] = {}
        """Serial -> the id it was confirmed with."""
        self._last_seen: dict[int, int] = {}
        """Serial -> the latest instant held that has it (ids are forgotten once it is published)."""

    def __len__(self) -> int:
        return len(self._held)

    def push(self, seq: int, t_ns: int, sensors_used: list[str], tracks: Sequence[TrackSnapshot]) -> None:
        """Hold one instant's tracks (all of them, tentative ones too)."""
        self._held.append(_Held(seq, t_ns, list(sensors_used), list(tracks)))
        for tr in tracks:
            if tr.track_id:
                self._ids[tr.serial] = tr.track_id
            self._last_seen[tr.serial] = t_ns

    def due(self, now_ns: int) -> LaggedInstant | None:
        """The oldest held instant once ``lag_ns`` has passed since it (one per call), else None."""
        if not self._held or self._held[0].t_ns > now_ns - self.lag_ns:
            return None
        return self._release(self._held.popleft())

    def flush(self) -> list[LaggedInstant]:
        """Every instant still held, oldest first (the end of a recorded run)."""
        out = [self._release(h) for h in self._held]
        self._held.clear()
        return out

    def _release(self, held: _Held) -> LaggedInstant:
        out: list[tuple[TrackSnapshot, str]] = []
        for tr in held.tracks:
            tid = self._ids.get(tr.serial, "")
            if tid and (tr.reported or (not tr.confirmed and tr.placed)):
                out.append((tr, tid))
        for tr in held.tracks:  # forget what no held instant needs any more
            if self._last_seen.get(tr.serial) == held.t_ns:
                self._last_seen.pop(tr.serial, None)
                self._ids.pop(tr.serial, None)
        return LaggedInstant(held.seq, held.t_ns, held.sensors_used, out)
