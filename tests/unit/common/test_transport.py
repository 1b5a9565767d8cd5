"""Inbox and TypedPublisher: bad payloads counted and dropped, ring drops oldest, FIFO drops newest, no blocking.
KeyedInbox (one bounded buffer per key, refusal before decoding) and KeyCensus (counts, pauses when flooded)."""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

import pytest
import zenoh

from common.codec import MAX_PAYLOAD_BYTES, encode
from common.schema import Blob, Features, PtzCommand
from common.session import SessionSettings, open_session, wait_until
from common.transport import Inbox, KeyCensus, KeyedInbox, TypedPublisher


@dataclass
class FakePayload:
    data: bytes

    def to_bytes(self) -> bytes:
        return self.data

    def __len__(self) -> int:
        return len(self.data)


@dataclass
class FakeSample:
    key_expr: str
    payload: FakePayload
    kind: Any = field(default_factory=lambda: zenoh.SampleKind.PUT)


class FakeSubscriber:
    def __init__(self) -> None:
        self.undeclared = False

    def undeclare(self) -> None:
        self.undeclared = True


class FakeSession:
    """Stands in for zenoh: records the callback so the test can play zenoh's callback thread."""

    def __init__(self) -> None:
        self.callbacks: dict[str, Callable[[Any], None]] = {}
        self.subscriber = FakeSubscriber()

    def declare_subscriber(self, key_expr: str, callback: Callable[[Any], None]) -> FakeSubscriber:
        self.callbacks[key_expr] = callback
        return self.subscriber

    def deliver(self, key: str, data: bytes) -> None:
        self.callbacks[key](FakeSample(key, FakePayload(data)))


def feat(seq: int, sensor: str = "cam1") -> Features:
    return Features(sensor_id=sensor, seq=seq, stamp_ns=seq, frame_index=seq)


KEY = "pano/@v1/sensor/cam1/features"


def test_decodes_on_the_consumer_side() -> None:
    s = FakeSession()
    inbox = Inbox(s, KEY, Features)
    s.deliver(KEY, encode(feat(1)))
    s.deliver(KEY, encode(feat(2)))
    assert len(inbox) == 2  # still undecoded bytes
    got = inbox.drain()
    assert [r.msg for r in got] == [feat(1), feat(2)]
    assert all(r.key == KEY and r.arrival_ns > 0 for r in got)
    assert inbox.drain() == []
    assert (inbox.counters.received, inbox.counters.decoded, inbox.counters.decode_errors) == (2, 2, 0)


def test_bad_payloads_are_counted_dropped_and_logged_rate_limited(caplog: pytest.LogCaptureFixture) -> None:
    s = FakeSession()
    inbox = Inbox(s, KEY, Features, log_every_s=60.0)
    bad = [b"", b"\xc1", encode(PtzCommand(manager_id="m", seq=1, stamp_ns=1, sensor_id="c", pan_rad=0, tilt_rad=0))]
    with caplog.at_level(logging.WARNING, logger="common.transport"):
        s.deliver(KEY, bad[0])
        s.deliver(KEY, encode(feat(1)))
        for b in bad * 3:
            s.deliver(KEY, b)
        s.deliver(KEY, encode(feat(2)))
        got = inbox.drain()
    assert [r.msg.seq for r in got] == [1, 2]
    assert inbox.counters.decode_errors == 10
    assert inbox.counters.decoded == 2
    assert inbox.counters.received == 12
    warnings = [r for r in caplog.records if "bad payload" in r.getMessage()]
    assert len(warnings) == 1, "one warning per log interval, not one per bad payload"
    assert KEY in warnings[0].getMessage()


def test_get_skips_bad_payloads() -> None:
    s = FakeSession()
    inbox = Inbox(s, KEY, Features)
    s.deliver(KEY, b"junk")
    s.deliver(KEY, encode(feat(5)))
    r = inbox.get(timeout_s=1.0)
    assert r is not None and r.msg.seq == 5
    assert inbox.counters.decode_errors == 1


def test_oversize_payloads_are_refused_before_buffering() -> None:
    s = FakeSession()
    inbox = Inbox(s, KEY, Features, capacity=8)
    for _ in range(50):
        s.deliver(KEY, b"\x00" * (MAX_PAYLOAD_BYTES + 1))
    s.deliver(KEY, encode(feat(7)))
    assert len(inbox) == 1  # nothing oversize was ever held
    assert [r.msg.seq for r in inbox.drain()] == [7]
    assert inbox.counters.decode_errors == 50
    assert inbox.counters.received == 51


def test_ring_drops_the_oldest() -> None:
    s = FakeSession()
    inbox = Inbox(s, KEY, Features, capacity=3, drop_oldest=True)
    for i in range(5):
        s.deliver(KEY, encode(feat(i)))
    assert [r.msg.seq for r in inbox.drain()] == [2, 3, 4]
    assert inbox.counters.dropped == 2


def test_fifo_drops_the_newest() -> None:
    s = FakeSession()
    inbox = Inbox(s, KEY, Features, capacity=3, drop_oldest=False)
    for i in range(5):
        s.deliver(KEY, encode(feat(i)))
    assert [r.msg.seq for r in inbox.drain()] == [0, 1, 2]
    assert inbox.counters.dropped == 2
    assert inbox.counters.received == 5


def test_callback_never_blocks_even_when_full() -> None:
    s = FakeSession()
    inbox = Inbox(s, KEY, Features, capacity=1, drop_oldest=False)
    t0 = time.monotonic()
    for i in range(2000):
        s.deliver(KEY, encode(feat(i)))
    assert time.monotonic() - t0 < 2.0
    assert len(inbox) == 1 and inbox.counters.dropped == 1999


def test_get_times_out_with_none() -> None:
    inbox = Inbox(FakeSession(), KEY, Features)
    t0 = time.monotonic()
    assert inbox.get(timeout_s=0.05) is None
    assert time.monotonic() - t0 >= 0.04


def test_get_wakes_when_a_sample_arrives_from_another_thread() -> None:
    s = FakeSession()
    inbox = Inbox(s, KEY, Features)
    threading.Timer(0.05, lambda: s.deliver(KEY, encode(feat(9)))).start()
    r = inbox.get(timeout_s=5.0)
    assert r is not None and r.msg.seq == 9


def test_delete_samples_are_counted_not_decoded() -> None:
    s = FakeSession()
    inbox = Inbox(s, KEY, Features)
    s.callbacks[KEY](FakeSample(KEY, FakePayload(b""), zenoh.SampleKind.DELETE))
    s.deliver(KEY, encode(feat(1)))
    assert [r.msg.seq for r in inbox.drain()] == [1]
    assert (inbox.counters.deletes, inbox.counters.decode_errors, inbox.counters.received) == (1, 0, 1)


def test_close_undeclares() -> None:
    s = FakeSession()
    inbox = Inbox(s, KEY, Features)
    inbox.close()
    assert s.subscriber.undeclared


# -- with a real zenoh session (peer, local delivery only: no network) ---------------


@pytest.fixture
def session() -> Iterator[Any]:
    with open_session(SessionSettings(mode="peer")) as s:
        yield s


@pytest.mark.parametrize("reliable_block", [False, True])
def test_typed_publisher_to_inbox(session: Any, reliable_block: bool) -> None:
    inbox = Inbox(session, "pano/@v1/sensor/*/features", Features)
    pubs = [TypedPublisher(session, f"pano/@v1/sensor/{s}/features", reliable_block=reliable_block) for s in ("a", "b")]
    for i in range(10):
        pubs[i % 2].put(feat(i, sensor="ab"[i % 2]))
    got: list[Any] = []

    def all_ten() -> bool:
        got.extend(inbox.drain())
        return len(got) == 10

    assert wait_until(all_ten, 5.0)
    assert [r.msg.seq for r in got] == list(range(10))
    assert {r.key for r in got} == {"pano/@v1/sensor/a/features", "pano/@v1/sensor/b/features"}
    for p in pubs:
        p.close()
    inbox.close()


def test_typed_publisher_refuses_invalid_messages(session: Any, caplog: pytest.LogCaptureFixture) -> None:
    inbox = Inbox(session, "pano/@v1/sensor/v/features", Features)
    pub = TypedPublisher(session, "pano/@v1/sensor/v/features", log_every_s=60.0)
    bad_id = Features(sensor_id="Not An Id", seq=1, stamp_ns=1, frame_index=1)
    bad_seq = Features(sensor_id="v", seq=-1, stamp_ns=1, frame_index=1)
    with caplog.at_level(logging.WARNING, logger="common.transport"):
        assert pub.put(bad_id) is False
        assert pub.put(bad_seq) is False
        assert pub.put(feat(7, sensor="v")) is True
    r = inbox.get(timeout_s=5.0)
    assert r is not None and r.msg.seq == 7
    assert inbox.get(timeout_s=0.2) is None, "an invalid message went out"
    assert (pub.sent, pub.invalid) == (1, 2)
    warnings = [rec.getMessage() for rec in caplog.records if "not sending" in rec.getMessage()]
    assert len(warnings) == 1 and "$.sensor_id" in warnings[0]
    pub.close()
    inbox.close()


def test_real_session_bad_payload_and_delete(session: Any) -> None:
    inbox = Inbox(session, "pano/@v1/sensor/x/features", Features)
    session.put("pano/@v1/sensor/x/features", b"\x00\x01not msgpack", encoding=zenoh.Encoding("application/msgpack"))
    session.delete("pano/@v1/sensor/x/features")
    session.put("pano/@v1/sensor/x/features", encode(feat(3)))
    r = inbox.get(timeout_s=5.0)
    assert r is not None and r.msg.seq == 3
    assert inbox.counters.decode_errors == 1
    assert inbox.counters.deletes == 1
    inbox.close()


# -- keyed inbox and census --------------------------------------------------------------------------------
HEAD = "pano/@v1/sensor/"


class Session:
    """A fake zenoh session: one callback per declared key expression; the test plays zenoh's thread."""

    def __init__(self) -> None:
        self.callbacks: dict[str, Callable[[Any], None]] = {}
        self.declared = 0

    def declare_subscriber(self, key_expr: str, callback: Callable[[Any], None], **_: Any) -> FakeSubscriber:
        self.callbacks[key_expr] = callback
        self.declared += 1
        sub = FakeSubscriber()
        original = sub.undeclare

        def undeclare() -> None:
            original()
            self.callbacks.pop(key_expr, None)

        sub.undeclare = undeclare  # type: ignore[method-assign]
        return sub

    def deliver(self, via: str, key: str, data: bytes) -> bool:
        cb = self.callbacks.get(via)
        if cb is None:
            return False
        cb(FakeSample(key, FakePayload(data)))
        return True


def _blob() -> Blob:
    return Blob(local_id=1, bearing_rad=0.5, width_rad=0.1, top_elev_rad=0.1, bottom_elev_rad=-0.3, bbox_u_px=1.0,
                bbox_v_px=1.0, bbox_w_px=10.0, bbox_h_px=30.0, hist=[0.015625] * 64)  # fmt: skip


def keyed_feat(sid: str, seq: int) -> bytes:
    return encode(Features(sensor_id=sid, seq=seq, stamp_ns=1_000 + seq, frame_index=seq))


def test_a_flooded_key_pushes_out_only_its_own_samples_and_counts_them() -> None:
    s = Session()
    keys = [f"{HEAD}a/features", f"{HEAD}b/features"]
    inbox = KeyedInbox(s, keys, Features, capacity=4)
    s.deliver(keys[1], keys[1], keyed_feat("b", 0))
    for i in range(1000):  # someone floods a's key
        s.deliver(keys[0], keys[0], keyed_feat("a", i))
    s.deliver(keys[1], keys[1], keyed_feat("b", 1))
    raw = inbox.drain_raw()
    got = [(k.split("/")[3], inbox.decode(k, d)) for k, d in raw]
    assert [(sid, m.seq) for sid, m in got if m is not None and sid == "b"] == [("b", 0), ("b", 1)]
    assert [m.seq for sid, m in got if m is not None and sid == "a"] == [996, 997, 998, 999]
    assert inbox.counters.dropped == 996 and inbox.counters.received == 1002
    assert inbox.drain_raw() == []


def test_a_key_over_its_byte_rate_loses_its_largest_samples_before_copy_and_holds_few_bytes() -> None:
    """A sender flooding 200 KB frames at hundreds a second beside its own small frames: the large ones beyond its
    budget are dropped on arrival (never copied), the small ones still get through, and what waits is bounded in
    bytes as well as in count."""
    s = Session()
    key = f"{HEAD}a/features"
    inbox = KeyedInbox(s, [key], Features, capacity=16, rate_bytes_per_s=2e6, max_key_bytes=2_000_000)
    big = encode(Features(sensor_id="a", seq=0, stamp_ns=1, frame_index=0, blobs=[_blob()] * 256))
    assert len(big) > 100_000
    small = keyed_feat("a", 1)
    for i in range(600):  # one second of flood, with the camera's own 15 frames among it
        s.deliver(key, key, big)
        if i % 40 == 0:
            s.deliver(key, key, small)
    c = inbox.counters
    assert c.over_rate >= 580  # ~2 MB of budget: some 10 large frames at most got in
    raw = inbox.drain_raw()
    assert sum(len(d) for _, d in raw) <= 2_000_000
    assert sum(1 for _, d in raw if d == small) >= 10  # the camera's small frames pass the budget


def test_keys_beyond_max_keys_are_dropped_and_counted_and_bad_payloads_counted_on_decode() -> None:
    s = Session()
    wild = f"{HEAD}*/features"
    inbox = KeyedInbox(s, [wild], Features, capacity=2, max_keys=3)
    for i in range(10):
        s.deliver(wild, f"{HEAD}s{i}/features", keyed_feat(f"s{i}", 0))
    raw = inbox.drain_raw()
    assert len(raw) == 3 and inbox.counters.dropped == 7
    s.deliver(wild, f"{HEAD}s0/features", b"\xc1 not msgpack")
    ((key, data),) = inbox.drain_raw()
    assert inbox.decode(key, data) is None and inbox.counters.decode_errors == 1


def test_census_counts_unknown_senders_only_and_pauses_when_flooded() -> None:
    s = Session()
    census = KeyCensus(s, f"{HEAD}**", HEAD, frozenset({"pano1"}), max_rate_hz=50.0, pause_s=0.0, max_ids=2)
    via = f"{HEAD}**"
    for _ in range(5):
        s.deliver(via, f"{HEAD}pano1/features", b"")  # a fused sensor: not counted
        s.deliver(via, f"{HEAD}evil/features", b"")
        s.deliver(via, f"{HEAD}evil/info", b"")
        s.deliver(via, f"{HEAD}stray/status", b"")
        s.deliver(via, f"{HEAD}third/features", b"")  # beyond max_ids: counted under ""
    assert census.take() == {"evil": 10, "stray": 5, "": 5}
    assert census.take() == {}
    assert not census.partial
    # A flood: more than max_rate_hz over the last window pauses counting (the subscriber goes).
    census._window_t -= 1.0  # the window is a second old
    for i in range(200):
        s.deliver(via, f"{HEAD}f{i}/features", b"")
    census.tick()
    assert census.partial and not s.deliver(via, f"{HEAD}evil/features", b"")
    census.tick()  # pause_s = 0: listening again at once
    assert s.deliver(via, f"{HEAD}evil/features", b"") and s.declared == 2
    census.close()
