"""Which SensorInfo the manager believes: the sensor's own answer, not whatever was last put on its key.

A SensorInfo put on ``sensor/{id}/info`` (live, or from the publisher's cache)
can come from anyone who may publish there: a buggy client reusing the id, or
an impostor on an open router. A put that *changes* what the manager holds is
therefore not taken; it only makes the manager ask the sensor again (a ``get``
on its queryable), and the answer is taken. So a static camera's pose never
jumps on one put. The first SensorInfo of a sensor is taken from a put (the
camera must not wait for a query) and confirmed by a read at once.

Reads also come on a period (``refresh_ns``) and whenever the sensor's
liveliness token comes back, so anything forged that got in (a first put
before the real sensor's) is replaced by the sensor's own answer within one
period of the impostor stopping.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import msgspec

from common.schema import SensorInfo

__all__ = ["InfoGate"]


def _same(a: SensorInfo, b: SensorInfo) -> bool:
    """Equal but for seq and stamp (a re-stamped copy of the same facts)."""
    return msgspec.structs.replace(a, seq=0, stamp_ns=0) == msgspec.structs.replace(b, seq=0, stamp_ns=0)


@dataclass(slots=True)
class InfoGate:
    """Holds each sensor's believed SensorInfo and says when to read it again.

    Args:
        refresh_ns: re-read every sensor this often.
        min_gap_ns: never read one sensor more often than this (a flood of changed puts costs a few reads).
    """

    refresh_ns: int
    min_gap_ns: int = 250_000_000
    held: dict[str, SensorInfo] = field(default_factory=dict)
    last_read_ns: dict[str, int] = field(default_factory=dict)
    wanted: set[str] = field(default_factory=set)
    """Sensors to read as soon as ``min_gap_ns`` allows (a changed put, a token that came back)."""
    ignored_puts: int = 0
    """Puts that would have changed a held SensorInfo (each answered by a read instead)."""

    def offer_put(self, info: SensorInfo) -> SensorInfo | None:
        """A put (or cached sample) on the sensor's key: the info to apply now, or None."""
        sid = info.sensor_id
        held = self.held.get(sid)
        if held is None:
            self.held[sid] = info
            self.wanted.add(sid)
            return info
        if not _same(held, info):
            self.ignored_puts += 1
            self.wanted.add(sid)
        return None

    def offer_read(self, info: SensorInfo, now_ns: int) -> SensorInfo | None:
        """The sensor's queryable answered: the info to apply (None when nothing changed)."""
        sid = info.sensor_id
        self.last_read_ns[sid] = now_ns
        held = self.held.get(sid)
        self.held[sid] = info
        return None if held is not None and _same(held, info) else info

    def came_back(self, sensor_id: str) -> None:
        """The sensor's liveliness token appeared (a restart may have changed its facts)."""
        self.wanted.add(sensor_id)

    def due(self, now_ns: int, candidates: set[str]) -> list[str]:
        """Sensors among ``candidates`` to read now; they count as read from now on."""
        out = []
        for sid in sorted(candidates):
            last = self.last_read_ns.get(sid)
            if last is not None and now_ns - last < self.min_gap_ns:
                continue
            if sid in self.wanted or last is None or now_ns - last >= self.refresh_ns:
                out.append(sid)
                self.wanted.discard(sid)
                self.last_read_ns[sid] = now_ns
        return out
