"""Track history: the in-memory path of every track, its append-only log on disk, and the id counter.

The log survives a manager restart (kill -9 included): each state is appended
to the current segment file as ``<u32 little-endian length><msgpack Track>``
and flushed every tick; a new segment starts every ``segment_s`` seconds and
segments older than ``retain_s`` are deleted. At start the segments covering
the last ``history_s`` are read back (a torn last record is ignored), so
``?history=`` answers include what happened before the restart.

Track ids are ``{manager_id}-{n}``. The counter is persisted by reserving
blocks: the file ``next_id`` holds an upper bound of every id handed out, and
is advanced (atomically: write, fsync, rename) before an id beyond it is
used. A restarted manager starts above the bound, so ids never repeat, even
after a crash.
"""

from __future__ import annotations

import logging
import os
import struct
from collections import deque
from collections.abc import Iterable
from pathlib import Path
from typing import BinaryIO

from common.codec import decode, encode
from common.errors import ConfigError, SchemaError
from common.schema import Track

__all__ = ["IdAllocator", "TrackLog", "TrackStore", "read_segments"]

logger = logging.getLogger(__name__)

_LEN = struct.Struct("<I")
_MAX_RECORD = 1 << 20


class IdAllocator:
    """Unique, never-repeating track ids ``{manager_id}-{n}`` backed by a reservation file.

    Args:
        state_dir: directory of the ``next_id`` file (created).
        manager_id: the id prefix.
        block: ids reserved per file write.
    """

    def __init__(self, state_dir: str | Path, manager_id: str, block: int = 64) -> None:
        self.dir = Path(state_dir)
        try:
            self.dir.mkdir(parents=True, exist_ok=True)
        except OSError as err:
            raise ConfigError(f"cannot create the manager state directory {self.dir}: {err.strerror}") from err
        self.path = self.dir / "next_id"
        self.manager_id = manager_id
        self.block = block
        self.n = self._read()
        self.reserved = self.n
        self._reserve(self.n + block)

    def _read(self) -> int:
        try:
            text = self.path.read_text().strip()
        except FileNotFoundError:
            return 0
        except OSError as err:
            raise ConfigError(f"cannot read {self.path}: {err.strerror}") from err
        try:
            return max(0, int(text))
        except ValueError as err:
            raise ConfigError(f"{self.path}: expected an integer id counter, got {text[:40]!r}") from err

    def _reserve(self, upto: int) -> None:
        tmp = self.path.with_suffix(".tmp")
        with open(tmp, "w") as fh:
            fh.write(f"{upto}\n")
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, self.path)
        self.reserved = upto

    def __call__(self) -> str:
        """The next id."""
        self.n += 1
        if self.n > self.reserved:
            self._reserve(self.n + self.block)
        return f"{self.manager_id}-{self.n}"


STATE_BYTES = 575
"""Memory one Track state takes in the store (tracemalloc of 10,000 states as the manager makes them)."""


class TrackStore:
    """Per-track paths in memory, at most ``rate_hz`` states per track, ``history_s`` long, ``max_mb`` in all.

    States are kept in the order they came (the fusion instants': time order), so the oldest of all goes first
    when either bound is reached: memory is bounded by the configuration, not by how many people came by.
    """

    def __init__(self, history_s: float = 600.0, rate_hz: float = 5.0, max_mb: float = 64.0) -> None:
        self.history_ns = int(history_s * 1e9)
        self.min_step_ns = int(0.8e9 / rate_hz) if rate_hz > 0 else 0  # 0.8: tolerate tick jitter
        self.max_states = max(1, int(max_mb * 2**20 / STATE_BYTES))
        self.paths: dict[str, deque[Track]] = {}
        self._order: deque[str] = deque()
        """The track id of every state kept, oldest first."""

    def add(self, track: Track) -> bool:
        """Keep a state (False if too soon after the previous kept one)."""
        path = self.paths.get(track.track_id)
        if path is None:
            path = self.paths[track.track_id] = deque()
        elif (path and track.stamp_ns - path[-1].stamp_ns < self.min_step_ns) or (
            path and track.stamp_ns <= path[-1].stamp_ns
        ):
            return False
        path.append(track)
        self._order.append(track.track_id)
        if len(self._order) > self.max_states:
            self._drop_oldest()
        return True

    def _drop_oldest(self) -> None:
        tid = self._order.popleft()
        path = self.paths.get(tid)
        if path:
            path.popleft()
        if not path:
            self.paths.pop(tid, None)

    def prune(self, now_ns: int) -> None:
        """Forget the states older than ``history_s`` before ``now_ns``."""
        cutoff = now_ns - self.history_ns
        while self._order:
            path = self.paths.get(self._order[0])
            if path and path[0].stamp_ns >= cutoff:
                break
            self._drop_oldest()

    def __len__(self) -> int:
        return len(self._order)

    def latest(self, track_id: str) -> Track | None:
        path = self.paths.get(track_id)
        return path[-1] if path else None

    def path(self, track_id: str, since_ns: int) -> list[Track]:
        """States of a track from ``since_ns`` on, oldest first."""
        return [t for t in self.paths.get(track_id, ()) if t.stamp_ns >= since_ns]

    def ids(self) -> list[str]:
        return list(self.paths)


def read_segments(directory: str | Path, since_ns: int) -> list[Track]:
    """Every Track logged at or after ``since_ns`` (segments named by start time), oldest first."""
    d = Path(directory)
    out: list[Track] = []
    if not d.is_dir():
        return out
    segs = sorted(d.glob("tracks-*.log"))
    starts = [_seg_start(p) for p in segs]
    for i, p in enumerate(segs):
        nxt = starts[i + 1] if i + 1 < len(segs) else None
        if nxt is not None and nxt < since_ns:
            continue  # the whole segment is older than wanted
        try:
            data = p.read_bytes()
        except OSError as err:
            logger.warning("cannot read track log %s: %s", p, err.strerror)
            continue
        pos = 0
        while pos + _LEN.size <= len(data):
            (n,) = _LEN.unpack_from(data, pos)
            if n > _MAX_RECORD or pos + _LEN.size + n > len(data):
                break  # torn record (crash mid-write)
            rec = data[pos + _LEN.size : pos + _LEN.size + n]
            pos += _LEN.size + n
            try:
                tr = decode(rec, Track)
            except SchemaError:
                continue
            if tr.stamp_ns >= since_ns:
                out.append(tr)
    out.sort(key=lambda t: t.stamp_ns)
    return out


def _seg_start(p: Path) -> int:
    try:
        return int(p.stem.split("-", 1)[1])
    except (IndexError, ValueError):
        return 0


class TrackLog:
    """Append-only segment files of Track states.

    Args:
        directory: where segments live (created).
        segment_s: seconds per segment.
        retain_s: segments older than this are deleted.
    """

    def __init__(self, directory: str | Path, segment_s: float = 60.0, retain_s: float = 3600.0) -> None:
        self.dir = Path(directory)
        try:
            self.dir.mkdir(parents=True, exist_ok=True)
        except OSError as err:
            raise ConfigError(f"cannot create the track log directory {self.dir}: {err.strerror}") from err
        self.segment_ns = int(segment_s * 1e9)
        self.retain_ns = int(retain_s * 1e9)
        self._fh: BinaryIO | None = None
        self._start_ns = 0
        self.written = 0

    def _open(self, stamp_ns: int) -> None:
        self.close()
        self._start_ns = stamp_ns
        self._fh = open(self.dir / f"tracks-{stamp_ns:020d}.log", "ab")  # noqa: SIM115 - kept open across ticks
        self._expire(stamp_ns)

    def _expire(self, now_ns: int) -> None:
        for p in sorted(self.dir.glob("tracks-*.log")):
            start = _seg_start(p)
            if start < now_ns - self.retain_ns and start != self._start_ns:
                try:
                    p.unlink()
                except OSError as err:
                    logger.warning("cannot delete old track log %s: %s", p, err.strerror)

    def append(self, tracks: Iterable[Track], stamp_ns: int) -> None:
        """Write states and flush (one tick)."""
        if self._fh is None or stamp_ns - self._start_ns >= self.segment_ns:
            self._open(stamp_ns)
        fh = self._fh
        assert fh is not None
        buf = bytearray()
        for t in tracks:
            data = encode(t)
            buf += _LEN.pack(len(data))
            buf += data
            self.written += 1
        if buf:
            fh.write(buf)
            fh.flush()

    def close(self) -> None:
        if self._fh is not None:
            try:
                self._fh.close()
            except OSError as err:
                logger.warning("closing the track log: %s", err.strerror)
            self._fh = None
