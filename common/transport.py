"""Typed publish/subscribe on top of a zenoh session.

Zenoh callbacks must never block (docs/zenoh.md §5.2-5.3): a slow callback
stalls the session's receive path for every subscriber. So the callback here
only copies the payload bytes into a bounded buffer; decoding and validation
happen on the consumer's thread when it calls :meth:`Inbox.drain` or
:meth:`Inbox.get`. Streams (features, tracks) use a ring buffer that drops
the oldest sample when full; commands use a FIFO that refuses the newest.

Bad payloads are counted, logged at most once per ``log_every_s`` and
dropped; they never raise into the consumer.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

import msgspec
import zenoh

from common.codec import MAX_PAYLOAD_BYTES, decode, encode
from common.errors import SchemaError
from common.session import MSGPACK

__all__ = ["Counters", "Inbox", "KeyCensus", "KeyedInbox", "Received", "TypedPublisher"]

logger = logging.getLogger(__name__)

T = TypeVar("T")

OVER_RATE_S = 1.0
"""A key that lost a sample to its byte budget counts as over its rate for this long (KeyedInbox)."""


@dataclass(slots=True)
class Counters:
    """What an inbox has seen; read by status messages."""

    received: int = 0
    decoded: int = 0
    decode_errors: int = 0
    dropped: int = 0
    """Samples lost to a full buffer (by count or bytes), or over their key's byte rate."""
    over_rate: int = 0
    """Of those, samples dropped on arrival because their key was over its byte rate: never copied nor decoded."""
    deletes: int = 0
    """DELETE samples (no payload) seen and ignored."""


@dataclass(frozen=True, slots=True)
class Received(Generic[T]):
    """One decoded sample."""

    key: str
    msg: T
    arrival_ns: int
    """Local wall-clock time the payload arrived (time.time_ns)."""


class Inbox(Generic[T]):
    """A zenoh subscriber whose samples are decoded on the consumer's side.

    Args:
        session: an open zenoh session.
        key_expr: what to subscribe to.
        msg_type: the schema type every payload must decode as.
        capacity: most undecoded samples held; when full, ``drop_oldest``
            drops the oldest (streams), otherwise the newest (commands).
        log_every_s: at most one warning about bad payloads per this interval.
    """

    def __init__(
        self,
        session: Any,
        key_expr: str,
        msg_type: type[T],
        *,
        capacity: int = 1024,
        drop_oldest: bool = True,
        log_every_s: float = 5.0,
    ) -> None:
        self.key_expr = key_expr
        self.msg_type = msg_type
        self.counters = Counters()
        self._capacity = capacity
        self._drop_oldest = drop_oldest
        self._buf: deque[tuple[str, bytes, int]] = deque()
        self._cond = threading.Condition()
        self._log_every_s = log_every_s
        self._last_log = 0.0
        self._suppressed = 0
        self._sub = session.declare_subscriber(key_expr, self._on_sample)

    def _on_sample(self, sample: Any) -> None:
        # Runs on zenoh's callback thread: copy and enqueue only.
        if sample.kind == zenoh.SampleKind.DELETE:
            with self._cond:
                self.counters.deletes += 1
            return
        if len(sample.payload) > MAX_PAYLOAD_BYTES:
            # Refuse before copying: a flood of oversize payloads must not grow memory.
            with self._cond:
                self.counters.received += 1
                self.counters.decode_errors += 1
            return
        item = (str(sample.key_expr), sample.payload.to_bytes(), time.time_ns())
        with self._cond:
            self.counters.received += 1
            if len(self._buf) >= self._capacity:
                self.counters.dropped += 1
                if not self._drop_oldest:
                    return
                self._buf.popleft()
            self._buf.append(item)
            self._cond.notify()

    def _decode(self, key: str, data: bytes, arrival_ns: int) -> Received[T] | None:
        try:
            msg = decode(data, self.msg_type)
        except SchemaError as err:
            self.counters.decode_errors += 1
            now = time.monotonic()
            if now - self._last_log >= self._log_every_s:
                extra = f" ({self._suppressed} more since last report)" if self._suppressed else ""
                logger.warning("dropped bad payload on %s: %s%s", key, err, extra)
                self._last_log = now
                self._suppressed = 0
            else:
                self._suppressed += 1
            return None
        self.counters.decoded += 1
        return Received(key, msg, arrival_ns)

    def drain(self) -> list[Received[T]]:
        """Decode and return everything buffered (never blocks)."""
        with self._cond:
            items = list(self._buf)
            self._buf.clear()
        out: list[Received[T]] = []
        for key, data, arrival in items:
            r = self._decode(key, data, arrival)
            if r is not None:
                out.append(r)
        return out

    def get(self, timeout_s: float | None = None) -> Received[T] | None:
        """Wait for the next valid message, up to ``timeout_s``; None on timeout."""
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        while True:
            with self._cond:
                while not self._buf:
                    remaining = None if deadline is None else deadline - time.monotonic()
                    if remaining is not None and remaining <= 0:
                        return None
                    self._cond.wait(remaining)
                key, data, arrival = self._buf.popleft()
            r = self._decode(key, data, arrival)
            if r is not None:
                return r

    def __len__(self) -> int:
        with self._cond:
            return len(self._buf)

    def close(self) -> None:
        """Undeclare the subscriber (its callback thread ends)."""
        try:
            self._sub.undeclare()
        except Exception as err:  # already closed with the session
            logger.debug("undeclare %s: %s", self.key_expr, err)


class KeyedInbox(Generic[T]):
    """Subscribers on several key expressions feeding one bounded buffer *per concrete key*.

    As :class:`Inbox`, the zenoh callback only copies bytes, and decoding is the
    consumer's (:meth:`drain_raw` then :meth:`decode`), so a consumer can refuse
    a sample by its key before paying for its decoding. Each concrete key has its
    own ``capacity`` and ``max_key_bytes`` (oldest dropped, counted): a sender
    flooding one key pushes out only that key's samples, and never holds more
    than that many bytes. With ``rate_bytes_per_s``, each key also has a byte
    budget (a token bucket holding at most one second of it, and always room for
    one largest payload): a sample that does not fit is dropped on arrival, before
    it is copied or decoded (``Counters.over_rate``), and for a second after such a
    drop the key is *over its rate*: every sample larger than ``large_bytes`` is
    dropped the same way. A sender over its rate loses its large messages, not its
    ordinary ones, and a flood of 200 KB frames costs a callback each, not a copy
    and a decode. At most ``max_keys`` concrete keys are held
    (a wildcard flooded with fresh keys cannot grow memory); samples of further
    keys are dropped and counted. ``advanced`` makes each subscriber a zenoh.ext
    AdvancedSubscriber that also fetches the publishers' cached samples
    (history) when it starts and when a publisher appears. ``notify`` is called
    (on zenoh's thread, so it must only signal, e.g. ``Event.set``) after each
    sample is buffered: a consumer waits for data instead of polling.
    """

    def __init__(
        self,
        session: Any,
        key_exprs: list[str],
        msg_type: type[T],
        *,
        capacity: int = 16,
        max_keys: int = 256,
        advanced: bool = False,
        log_every_s: float = 5.0,
        notify: Callable[[], None] | None = None,
        max_key_bytes: int = 16 * MAX_PAYLOAD_BYTES,
        rate_bytes_per_s: float = 0.0,
        large_bytes: int = MAX_PAYLOAD_BYTES,
    ) -> None:
        self.msg_type = msg_type
        self.counters = Counters()
        self._notify = notify
        self._capacity = capacity
        self._max_keys = max_keys
        self._max_key_bytes = max_key_bytes
        self._rate = rate_bytes_per_s
        self._burst = max(rate_bytes_per_s, MAX_PAYLOAD_BYTES)
        self._large = large_bytes
        self._bufs: dict[str, deque[bytes]] = {}
        self._bytes: dict[str, int] = {}
        self._buckets: dict[str, list[float]] = {}
        """Key -> [tokens, when last filled, until when it is over its rate (monotonic s)]: kept across drains, at
        most ``max_keys``."""
        self._lock = threading.Lock()
        self._log_every_s = log_every_s
        self._last_log = -math.inf
        self._subs: list[Any] = []
        try:
            for ke in key_exprs:
                if advanced:
                    from zenoh.ext import HistoryConfig, declare_advanced_subscriber

                    history = HistoryConfig(detect_late_publishers=True, max_samples=1)
                    self._subs.append(declare_advanced_subscriber(session, ke, self._on_sample, history=history))
                else:
                    self._subs.append(session.declare_subscriber(ke, self._on_sample))
        except Exception:
            self.close()
            raise

    def _on_sample(self, sample: Any) -> None:
        # zenoh's callback thread: copy and enqueue only.
        if sample.kind == zenoh.SampleKind.DELETE:
            with self._lock:
                self.counters.deletes += 1
            return
        size = len(sample.payload)
        key = str(sample.key_expr)
        with self._lock:
            self.counters.received += 1
            if size > MAX_PAYLOAD_BYTES:  # refused before copying: oversize payloads must not grow memory
                self.counters.decode_errors += 1
                return
            if self._rate > 0 and not self._spend(key, size):
                self.counters.dropped += 1
                self.counters.over_rate += 1
                return
        data = sample.payload.to_bytes()  # outside the lock: the consumer drains meanwhile
        with self._lock:
            buf = self._bufs.get(key)
            if buf is None:
                if len(self._bufs) >= self._max_keys:
                    self.counters.dropped += 1
                    return
                buf = self._bufs[key] = deque()
                self._bytes[key] = 0
            held = self._bytes[key] + len(data)
            while buf and (len(buf) >= self._capacity or held > self._max_key_bytes):
                held -= len(buf.popleft())
                self.counters.dropped += 1
            buf.append(data)
            self._bytes[key] = held
        if self._notify is not None:
            self._notify()

    def _spend(self, key: str, size: int) -> bool:
        """Take ``size`` bytes from ``key``'s budget if it has them (lock held)."""
        now = time.monotonic()
        bucket = self._buckets.get(key)
        if bucket is None:
            if len(self._buckets) >= self._max_keys:  # forget the keys whose budget has refilled: idle for a while
                refill_s = self._burst / self._rate
                for k in [k for k, (_, t, _) in self._buckets.items() if now - t > refill_s]:
                    del self._buckets[k]
            if len(self._buckets) >= self._max_keys:
                return False
            bucket = self._buckets[key] = [self._burst, now, 0.0]
        bucket[0] = min(self._burst, bucket[0] + (now - bucket[1]) * self._rate)
        bucket[1] = now
        if bucket[0] < size or (size > self._large and now < bucket[2]):
            bucket[2] = now + OVER_RATE_S
            return False
        bucket[0] -= size
        return True

    def drain_raw(self) -> list[tuple[str, bytes]]:
        """(key, payload) of everything buffered, each key's in arrival order (never blocks)."""
        with self._lock:
            bufs, self._bufs = self._bufs, {}
            self._bytes = {}
        return [(key, data) for key, buf in bufs.items() for data in buf]

    def decode(self, key: str, data: bytes) -> T | None:
        """Decode one payload; a bad one is counted, logged (rate-limited) and None."""
        try:
            msg = decode(data, self.msg_type)
        except SchemaError as err:
            with self._lock:
                self.counters.decode_errors += 1
            now = time.monotonic()
            if now - self._last_log >= self._log_every_s:
                self._last_log = now
                logger.warning("dropped bad payload on %s: %s", key, err)
            return None
        with self._lock:
            self.counters.decoded += 1
        return msg

    def close(self) -> None:
        for sub in self._subs:
            try:
                sub.undeclare()
            except Exception as err:  # already closed with the session
                logger.debug("undeclare: %s", err)
        self._subs.clear()


class KeyCensus:
    """Counts samples on a wildcard whose key chunk after ``head`` is not in ``known``, by that chunk.

    It only counts (no copy, no decode). A sender that floods faster than
    ``max_rate_hz`` (over ``window_s``) would cost the process a core: the
    census then stops listening for ``pause_s`` (the caller's :meth:`tick`
    undeclares it) and :attr:`partial` says its counts are lower bounds from
    then on.
    """

    def __init__(
        self,
        session: Any,
        key_expr: str,
        head: str,
        known: frozenset[str],
        *,
        max_rate_hz: float = 2000.0,
        pause_s: float = 5.0,
        max_ids: int = 1024,
        window_s: float = 0.25,
    ) -> None:
        self._session = session
        self._key_expr = key_expr
        self._head = head
        self._known = known
        self._max_rate_hz = max_rate_hz
        self._pause_s = pause_s
        self._max_ids = max_ids
        self._window_s = window_s
        self._lock = threading.Lock()
        self._new: dict[str, int] = {}
        self._window = 0
        self._window_t = time.monotonic()
        self._resume_t = 0.0
        self.partial = False
        self._sub: Any = None
        self._declare()

    def _declare(self) -> None:
        self._sub = self._session.declare_subscriber(
            self._key_expr, self._on_sample, allowed_origin=zenoh.Locality.REMOTE
        )

    def _on_sample(self, sample: Any) -> None:
        # zenoh's callback thread: a string split and a dict increment.
        key = str(sample.key_expr)
        if not key.startswith(self._head):
            return
        rest = key[len(self._head) :]
        cut = rest.find("/")
        sid = rest if cut < 0 else rest[:cut]
        if sid in self._known:
            return
        with self._lock:
            self._window += 1
            if sid in self._new or len(self._new) < self._max_ids:
                self._new[sid] = self._new.get(sid, 0) + 1
            else:
                self._new[""] = self._new.get("", 0) + 1

    def take(self) -> dict[str, int]:
        """Counts since the last call, by sender chunk ("" for senders beyond ``max_ids``)."""
        with self._lock:
            out, self._new = self._new, {}
        return out

    def tick(self) -> None:
        """Pause when flooded, resume after ``pause_s``; call it from the owner's loop (not zenoh's thread)."""
        now = time.monotonic()
        if self._sub is None:
            if now >= self._resume_t:
                self._window, self._window_t = 0, now
                self._declare()
            return
        elapsed = now - self._window_t
        if elapsed < self._window_s:
            return
        with self._lock:
            rate = self._window / elapsed
            self._window, self._window_t = 0, now
        if rate > self._max_rate_hz:
            logger.warning(
                "unlisted senders on %s at %.0f msg/s: counting paused for %.0f s (counts are lower bounds)",
                self._key_expr,
                rate,
                self._pause_s,
            )
            self.partial = True
            self.close()
            self._resume_t = now + self._pause_s

    def close(self) -> None:
        if self._sub is not None:
            try:
                self._sub.undeclare()
            except Exception as err:
                logger.debug("undeclare census: %s", err)
            self._sub = None


class TypedPublisher:
    """A zenoh publisher of one message type, with the msgpack encoding set.

    msgspec checks constraints only when decoding, so a sender could build a
    message every receiver refuses (a NaN bearing, a bad id) and never know.
    With ``validate`` (the default) each message is checked before it is
    sent: an invalid one is not sent, is counted in :attr:`invalid`, and is
    logged with its field path (at most once per ``log_every_s``).

    Args:
        reliable_block: BLOCK congestion control (tracks, commands) instead of
            DROP (high-rate features, where freshness beats completeness).
        validate: check each message against its schema before sending
            (a decode of the encoded bytes: a few µs per message).
        cache_samples: > 0 makes it a zenoh.ext AdvancedPublisher that keeps its last
            samples for late joiners (AdvancedSubscriber history) and announces itself
            (publisher detection); the session needs ``timestamping/enabled``.
    """

    def __init__(
        self,
        session: Any,
        key: str,
        *,
        reliable_block: bool = False,
        express: bool = True,
        validate: bool = True,
        log_every_s: float = 5.0,
        cache_samples: int = 0,
    ) -> None:
        self.key = key
        self.sent = 0
        self.invalid = 0
        """Messages not sent because they broke their schema (a bug in the sender)."""
        self._validate = validate
        self._log_every_s = log_every_s
        self._last_log = -math.inf
        cc = zenoh.CongestionControl.BLOCK if reliable_block else zenoh.CongestionControl.DROP
        if cache_samples > 0:
            from zenoh.ext import CacheConfig, declare_advanced_publisher

            self._pub = declare_advanced_publisher(
                session,
                key,
                encoding=MSGPACK,
                congestion_control=cc,
                express=express,
                cache=CacheConfig(max_samples=cache_samples),
                publisher_detection=True,
            )
        else:
            self._pub = session.declare_publisher(key, encoding=MSGPACK, congestion_control=cc, express=express)

    def put(self, msg: msgspec.Struct) -> bool:
        """Send ``msg``; returns False (and sends nothing) if it breaks its schema."""
        data = encode(msg)
        if self._validate:
            try:
                decode(data, type(msg))
            except SchemaError as err:
                self.invalid += 1
                now = time.monotonic()
                if now - self._last_log >= self._log_every_s:
                    self._last_log = now
                    logger.warning(
                        "not sending an invalid %s on %s (%d so far): %s",
                        type(msg).__name__,
                        self.key,
                        self.invalid,
                        err,
                    )
                return False
        self._pub.put(data)
        self.sent += 1
        return True

    def close(self) -> None:
        try:
            self._pub.undeclare()
        except Exception as err:
            logger.debug("undeclare publisher %s: %s", self.key, err)
