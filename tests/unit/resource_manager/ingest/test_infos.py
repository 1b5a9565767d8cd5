"""The SensorInfo gate: first facts applied at once, a changed put answered by a read, reads rate-limited."""

from __future__ import annotations

import msgspec

from common.schema import PanoramicModel, Pose, SensorInfo
from resource_manager.ingest.infos import InfoGate

MS = 1_000_000


def _info(seq: int, x_m: float = 0.0) -> SensorInfo:
    model = PanoramicModel(width_px=1080, height_px=162, f_v_px=256.0, v0_px=93.0)
    return SensorInfo(
        sensor_id="p1",
        seq=seq,
        stamp_ns=seq,
        kind="panoramic",
        model=model,
        pose=Pose(x_m=x_m, y_m=0.0, z_m=1.1, yaw_rad=0.0),
    )


def test_a_put_applies_only_the_first_facts_and_a_change_asks_for_a_read() -> None:
    gate = InfoGate(refresh_ns=10_000 * MS)
    first = _info(1)
    assert gate.offer_put(first) is first
    assert gate.offer_put(msgspec.structs.replace(first, seq=2, stamp_ns=2)) is None  # re-stamped: same facts
    assert gate.ignored_puts == 0
    assert gate.offer_put(_info(3, x_m=1.0)) is None  # changed: not trusted from a put
    assert gate.ignored_puts == 1 and "p1" in gate.wanted
    assert gate.due(0, {"p1"}) == ["p1"] and not gate.wanted
    moved = _info(4, x_m=1.0)
    assert gate.offer_read(moved, 0) is moved
    assert gate.offer_read(_info(5, x_m=1.0), 1) is None  # the read says nothing changed


def test_reads_are_due_on_refresh_and_never_closer_than_the_minimum_gap() -> None:
    gate = InfoGate(refresh_ns=1000 * MS, min_gap_ns=250 * MS)
    gate.offer_read(_info(1), 0)
    assert gate.due(500 * MS, {"p1"}) == []  # neither wanted nor stale
    gate.came_back("p1")
    assert gate.due(100 * MS, {"p1"}) == []  # wanted, but read 100 ms ago
    assert gate.due(300 * MS, {"p1"}) == ["p1"]
    assert gate.due(1200 * MS, {"p1"}) == []  # read at 300 ms: not stale yet
    assert gate.due(1300 * MS, {"p1", "p2"}) == ["p1", "p2"]  # stale, and never read
