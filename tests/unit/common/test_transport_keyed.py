"""KeyedInbox (one bounded buffer per key, refusal before decoding) and KeyCensus (counts, pauses when flooded)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from common.codec import encode
from common.schema import Features
from common.transport import KeyCensus, KeyedInbox
from tests.unit.common.test_transport import FakePayload, FakeSample, FakeSubscriber

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


def feat(sid: str, seq: int) -> bytes:
    return encode(Features(sensor_id=sid, seq=seq, stamp_ns=1_000 + seq, frame_index=seq))


def test_a_flooded_key_pushes_out_only_its_own_samples_and_counts_them() -> None:
    s = Session()
    keys = [f"{HEAD}a/features", f"{HEAD}b/features"]
    inbox = KeyedInbox(s, keys, Features, capacity=4)
    s.deliver(keys[1], keys[1], feat("b", 0))
    for i in range(1000):  # someone floods a's key
        s.deliver(keys[0], keys[0], feat("a", i))
    s.deliver(keys[1], keys[1], feat("b", 1))
    raw = inbox.drain_raw()
    got = [(k.split("/")[3], inbox.decode(k, d)) for k, d in raw]
    assert [(sid, m.seq) for sid, m in got if m is not None and sid == "b"] == [("b", 0), ("b", 1)]
    assert [m.seq for sid, m in got if m is not None and sid == "a"] == [996, 997, 998, 999]
    assert inbox.counters.dropped == 996 and inbox.counters.received == 1002
    assert inbox.drain_raw() == []


def test_keys_beyond_max_keys_are_dropped_and_counted_and_bad_payloads_counted_on_decode() -> None:
    s = Session()
    wild = f"{HEAD}*/features"
    inbox = KeyedInbox(s, [wild], Features, capacity=2, max_keys=3)
    for i in range(10):
        s.deliver(wild, f"{HEAD}s{i}/features", feat(f"s{i}", 0))
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
