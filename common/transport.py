"""Typed publish/subscribe on top of a zenoh session.

Zenoh callbacks must never block (notes/zenoh.md §5.2-5.3): a slow callback
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
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

import msgspec
import zenoh

from common.codec import MAX_PAYLOAD_BYTES, decode, encode
from common.errors import SchemaError
from common.session import MSGPACK

__all__ = ["Counters", "Inbox", "Received", "TypedPublisher"]

logger = logging.getLogger(__name__)

T = TypeVar("T")


@dataclass(slots=True)
class Counters:
    """What an inbox has seen; read by status messages."""

    received: int = 0
    decoded: int = 0
    decode_errors: int = 0
    dropped: int = 0
    """Samples lost to a full buffer."""
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
    ) -> None:
        self.key = key
        self.sent = 0
        self.invalid = 0
        """Messages not sent because they broke their schema (a bug in the sender)."""
        self._validate = validate
        self._log_every_s = log_every_s
        self._last_log = -math.inf
        self._pub = session.declare_publisher(
            key,
            encoding=MSGPACK,
            congestion_control=zenoh.CongestionControl.BLOCK if reliable_block else zenoh.CongestionControl.DROP,
            express=express,
        )

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
