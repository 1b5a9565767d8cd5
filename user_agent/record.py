"""Record everything under ``{prefix}/@v1/**`` into an MCAP file.

Per zenoh key the file holds (docs/zenoh.md §7.1):

* a **raw** channel (topic = the key, message encoding ``msgpack``, channel
  metadata ``zenoh_key`` and ``kind=raw``): the exact payload bytes, so
  ``replay`` republishes bit for bit;
* a **JSON** channel (topic ``/json/<key>``) with the message type's JSON
  schema (``pano.TrackSet``, …) so any MCAP tool shows the fields;
* and, for the 3D view in Foxglove, ``/scene/tracks`` and ``/scene/cameras``
  (``foxglove.SceneUpdate``) and ``/tf`` (``foxglove.FrameTransform``): foxglove-sdk's
  typed messages (:mod:`user_agent.foxglove`), protobuf-encoded with the schema each
  carries; mobile cameras are drawn, and their transforms written, where the
  manager's mutual calibration places them (``ManagerStatus.poses``), each time it does.

Log time is the local arrival time; publish time is the message's own
``stamp_ns``. Zenoh's callback only enqueues bytes; a writer thread decodes
and writes (never block a transport thread). When the writer cannot keep up
(a flood), raw sensor messages (features, SensorInfo, statuses, PTZ states)
are dropped first and never written more than
``max_lag_s`` late; every drop is counted per key in the file's metadata.
"""

from __future__ import annotations

import json
import logging
import threading
import time
from collections import deque
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import msgspec
from mcap.well_known import MessageEncoding, SchemaEncoding
from mcap.writer import CompressionType, Writer

from common.errors import ConfigError
from common.keys import VERSION, Keys
from common.schema import ManagerStatus, SensorInfo, TrackSet, ViewPlan
from user_agent.foxglove import CameraPlacements, FoxgloveMessage, tracks_scene
from user_agent.messages import decode_on_key, type_for_key

__all__ = ["META_NAME", "RAW_ENCODING", "RECORDER_META", "McapSink", "Recorder", "RecorderStatus"]

logger = logging.getLogger(__name__)

META_NAME = "panostereo"
"""Name of the MCAP metadata record holding the run's facts (site, epoch_ns, fps, room)."""
RAW_ENCODING = "msgpack"
RECORDER_META = "panostereo.recorder"
"""Metadata record of what the recorder wrote and lost (per key) and its worst lag."""


def keys_for(key: str) -> Keys | None:
    """The :class:`Keys` of a concrete key's prefix (None if not a versioned panostereo key)."""
    marker = f"/{VERSION}/"
    if marker not in key:
        return None
    try:
        return Keys(key.split(marker, 1)[0])
    except ConfigError:
        return None


class McapSink:
    """Writes zenoh samples into an MCAP file (raw + JSON + Foxglove channels).

    Args:
        path: output file (its folder is created).
        metadata: run facts stored as the ``panostereo`` metadata record.
        foxglove: also write the Foxglove scene channels.
    """

    def __init__(self, path: str | Path, metadata: dict[str, str] | None = None, foxglove: bool = True) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        try:
            self._fh = self.path.open("wb")
        except OSError as err:
            raise ConfigError(f"{self.path}: cannot write recording: {err.strerror}") from err
        self._w = Writer(self._fh, compression=CompressionType.ZSTD)
        self._w.start(profile="", library="panostereo")
        self._w.add_metadata(META_NAME, {k: str(v) for k, v in (metadata or {}).items()})
        self._foxglove = foxglove
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, int] = {}
        self._seq: dict[int, int] = {}
        self._cameras = CameraPlacements()
        self.plans: list[ViewPlan] = []
        """Every view plan written (the simulator's ground truth depends on them)."""
        self._lock = threading.Lock()
        self.messages = 0
        """Raw samples written."""
        self.undecodable = 0
        self._closed = False

    # -- registration -------------------------------------------------------
    def _schema(self, name: str, schema: dict[str, Any]) -> int:
        sid = self._schemas.get(name)
        if sid is None:
            sid = self._w.register_schema(
                name=name, encoding=SchemaEncoding.JSONSchema, data=json.dumps(schema).encode()
            )
            self._schemas[name] = sid
        return sid

    def _foxglove_channel(self, topic: str, msg: FoxgloveMessage, metadata: dict[str, str]) -> int:
        """The channel of a Foxglove message type, its schema as foxglove-sdk gives it (protobuf)."""
        cid = self._channels.get(topic)
        if cid is not None:
            return cid
        schema = msg.get_schema()
        sid = self._schemas.get(schema.name)
        if sid is None:
            sid = self._w.register_schema(name=schema.name, encoding=schema.encoding, data=bytes(schema.data))
            self._schemas[schema.name] = sid
        return self._channel(topic, schema.encoding, sid, metadata)

    def _channel(self, topic: str, encoding: str, schema_id: int, metadata: dict[str, str]) -> int:
        cid = self._channels.get(topic)
        if cid is None:
            cid = self._w.register_channel(
                topic=topic, message_encoding=encoding, schema_id=schema_id, metadata=metadata
            )
            self._channels[topic] = cid
        return cid

    def _add(self, cid: int, log_ns: int, pub_ns: int, data: bytes) -> None:
        seq = self._seq.get(cid, 0)
        self._seq[cid] = seq + 1
        self._w.add_message(channel_id=cid, log_time=log_ns, publish_time=pub_ns, sequence=seq, data=data)

    def add_foxglove(self, topic: str, msg: FoxgloveMessage, log_time_ns: int) -> None:
        """Write one Foxglove message on a channel of its own (e.g. a ground-truth scene)."""
        with self._lock:
            if self._closed:
                return
            self._add(self._foxglove_channel(topic, msg, {"kind": "extra"}), log_time_ns, log_time_ns, msg.encode())

    # -- samples ------------------------------------------------------------
    def write(self, key: str, data: bytes, log_time_ns: int) -> None:
        """Write one zenoh sample (raw bytes as received) and its decoded views."""
        with self._lock:
            if self._closed:
                return
            keys = keys_for(key)
            msg = decode_on_key(keys, key, data) if keys is not None else None
            pub_ns = int(getattr(msg, "stamp_ns", 0)) or log_time_ns
            raw = self._channel(
                key, RAW_ENCODING, 0, {"zenoh_key": key, "encoding": "application/msgpack", "kind": "raw"}
            )
            self._add(raw, log_time_ns, pub_ns, data)
            self.messages += 1
            if msg is None:
                self.undecodable += 1
                return
            if isinstance(msg, ViewPlan):
                self.plans.append(msg)
            mtype = type_for_key(keys, key) if keys is not None else None
            assert mtype is not None
            name = f"pano.{mtype.__name__}"
            sid = self._schemas.get(name)
            if sid is None:
                sid = self._schema(name, msgspec.json.schema(mtype))
            cid = self._channel(f"/json/{key}", MessageEncoding.JSON, sid, {"zenoh_key": key, "kind": "json"})
            self._add(cid, log_time_ns, pub_ns, msgspec.json.encode(msg))
            if self._foxglove:
                self._write_scene(msg, log_time_ns, pub_ns)

    def _write_fg(self, topic: str, msg: FoxgloveMessage, log_ns: int, pub_ns: int) -> None:
        self._add(self._foxglove_channel(topic, msg, {"kind": "foxglove"}), log_ns, pub_ns, msg.encode())

    def _write_scene(self, msg: Any, log_ns: int, pub_ns: int) -> None:
        if isinstance(msg, TrackSet):
            self._write_fg("/scene/tracks", tracks_scene(msg, self._cameras.camera_xyz), log_ns, pub_ns)
            return
        if not isinstance(msg, SensorInfo | ManagerStatus):
            return
        scene, tfs = self._cameras.update(msg, pub_ns)
        if scene is not None:
            self._write_fg("/scene/cameras", scene, log_ns, pub_ns)
        for tf in tfs:
            self._write_fg("/tf", tf, log_ns, pub_ns)

    def add_metadata(self, name: str, data: dict[str, str]) -> None:
        with self._lock:
            if not self._closed:
                self._w.add_metadata(name, {k: str(v) for k, v in data.items()})

    def close(self) -> None:
        """Finish the file (summary, indexes); safe to call twice."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            self._w.finish()
            self._fh.close()


@dataclass(frozen=True, slots=True)
class RecorderStatus:
    """How a recorder keeps up: what it wrote, what it lost and how far behind live it is."""

    written: int
    dropped: int
    """Samples lost, every reason."""
    dropped_raw: int
    """...of which raw sensor messages (``sensor/**``: features, SensorInfo, statuses; dropped first)."""
    lag_s: float
    """Age of the oldest sample waiting to be written (0: keeping up)."""
    max_lag_s: float
    """The most any written sample waited."""


class Recorder:
    """Subscribes to key expressions and feeds an :class:`McapSink` from a writer thread.

    The zenoh callback copies and queues only. The queue is bounded: what
    sensors publish (``sensor/**``: features, the bulk of a site's traffic,
    SensorInfo, statuses, PTZ states) waits in a part of its own and goes
    first when the writer falls behind: a raw message that waited
    ``max_lag_s`` (half a second: written samples stay within a second of
    live) is dropped rather than written late, and raw messages are dropped
    before anything else is. The derived data (tracks, manager statuses,
    pairs, plans) is dropped only when the whole queue is full. Every drop is
    counted per key (:attr:`drops`, at most ``max_keys`` keys, the rest under
    ""), and :meth:`stop` writes the counts into the file (metadata record
    ``panostereo.recorder``). At most ``max_keys`` distinct keys are recorded:
    a flood of fresh keys cannot grow the file's channel table.

    Args:
        session: an open zenoh session.
        key_expr: what to record (``Keys(prefix).all``), or several expressions.
        sink: where to write.
        capacity: most samples waiting, features and the rest together.
        raw_capacity: most raw sensor messages waiting.
        max_lag_s: a raw Feature that waited this long is dropped, not written.
    """

    def __init__(
        self,
        session: Any,
        key_expr: str | list[str],
        sink: McapSink,
        capacity: int = 20_000,
        *,
        raw_capacity: int = 2_000,
        max_lag_s: float = 0.5,
        max_keys: int = 2_048,
    ) -> None:
        self.sink = sink
        self.drops: dict[str, int] = {}
        self.dropped = 0
        self.dropped_raw = 0
        self.max_lag_ns = 0
        self._keys: set[str] = set()
        self._max_keys = max_keys
        self._high: deque[tuple[str, bytes, int]] = deque()
        self._low: deque[tuple[str, bytes, int]] = deque()
        self._capacity = capacity
        self._raw_capacity = min(raw_capacity, capacity)
        self._raw_marker = "/sensor/"
        self._lag_limit_ns = int(max_lag_s * 1e9)
        self._cond = threading.Condition()
        self._stop = False
        self._thread = threading.Thread(target=self._loop, name="mcap-writer", daemon=True)
        self._thread.start()
        exprs = [key_expr] if isinstance(key_expr, str) else list(key_expr)
        self._subs = [session.declare_subscriber(ke, self._on_sample) for ke in exprs]

    def _drop(self, key: str, raw: bool) -> None:
        """Count one lost sample (the caller holds the lock)."""
        self.dropped += 1
        if raw:
            self.dropped_raw += 1
        k = key if key in self.drops or len(self.drops) < self._max_keys else ""
        self.drops[k] = self.drops.get(k, 0) + 1

    def _on_sample(self, sample: Any) -> None:
        # zenoh's callback thread: decide, copy, queue; nothing else.
        key = str(sample.key_expr)
        raw = self._raw_marker in key
        with self._cond:
            if key not in self._keys:
                if len(self._keys) >= self._max_keys:
                    self._drop(key, raw)
                    return
                self._keys.add(key)
            full = len(self._high) + len(self._low) >= self._capacity
            if raw and (full or len(self._low) >= self._raw_capacity):
                self._drop(key, True)  # the newest, uncopied: the writer drops the stale ones
                return
            if full:
                if self._low:
                    old = self._low.popleft()
                    self._drop(old[0], True)
                else:
                    old = self._high.popleft()
                    self._drop(old[0], False)
        item = (key, sample.payload.to_bytes(), time.time_ns())
        with self._cond:
            (self._low if raw else self._high).append(item)
            self._cond.notify()

    def _next(self) -> tuple[str, bytes, int] | None:
        """The next sample to write, derived data before raw sensor messages; raw ones too old are dropped here."""
        with self._cond:
            while not self._high and not self._low and not self._stop:
                self._cond.wait(0.2)
            if self._high:
                return self._high.popleft()
            now = time.time_ns()
            while self._low:
                item = self._low.popleft()
                if now - item[2] <= self._lag_limit_ns:
                    return item
                self._drop(item[0], True)
            return None

    def _loop(self) -> None:
        while True:
            item = self._next()
            if item is None:
                with self._cond:
                    if self._stop and not self._high and not self._low:
                        return
                continue
            key, data, t = item
            self.sink.write(key, data, t)
            lag = time.time_ns() - t
            self.max_lag_ns = max(self.max_lag_ns, lag)

    @property
    def messages(self) -> int:
        return self.sink.messages

    def top_drops(self, n: int = 3) -> list[tuple[str, int]]:
        """The keys that lost the most samples so far ("" for keys beyond ``max_keys``), most first."""
        with self._cond:
            return sorted(self.drops.items(), key=lambda kv: (-kv[1], kv[0]))[:n]

    def status(self) -> RecorderStatus:
        """What it wrote and lost so far, and how far behind live it is now."""
        now = time.time_ns()
        with self._cond:
            oldest = min((q[0][2] for q in (self._high, self._low) if q), default=now)
            return RecorderStatus(
                self.sink.messages, self.dropped, self.dropped_raw, (now - oldest) / 1e9, self.max_lag_ns / 1e9
            )

    def stop(self, close: bool = True) -> None:
        """Undeclare, write what is buffered, record the drop counts and (unless ``close=False``) finish the file."""
        for sub in self._subs:
            try:
                sub.undeclare()
            except Exception as err:  # session already closed
                logger.debug("undeclare recorder: %s", err)
        with self._cond:
            self._stop = True
            self._cond.notify()
        self._thread.join(timeout=30)
        st = self.status()
        meta = {"dropped": str(st.dropped), "dropped_raw": str(st.dropped_raw),
                "max_lag_s": f"{st.max_lag_s:.3f}", "written": str(st.written)}  # fmt: skip
        with self._cond:
            meta |= {f"dropped:{k or '(other keys)'}": str(n) for k, n in sorted(self.drops.items())}
        self.sink.add_metadata(RECORDER_META, meta)
        if close:
            self.sink.close()
        if st.dropped:
            logger.warning(
                "recorder dropped %d samples (%d raw sensor messages) to stay within %.1f s of live",
                st.dropped,
                st.dropped_raw,
                self._lag_limit_ns / 1e9,
            )
