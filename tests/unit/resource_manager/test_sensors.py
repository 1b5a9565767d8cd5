"""The sensor registry (resource_manager/sensors.py): one owner of each sensor's info, presence, frames and timing,
one forget, one size bound."""

from __future__ import annotations

import msgspec

from common.schema import Features
from resource_manager.sensors import PRESENCE_PER_SENSOR, SensorRegistry
from tests.unit.resource_manager.synth import Cam, info_for

S = 1_000_000_000


def _frame(sensor_id: str, seq: int, stamp_ns: int) -> Features:
    return Features(sensor_id=sensor_id, seq=seq, stamp_ns=stamp_ns, frame_index=seq)


def _registry(capacity: int = 4) -> SensorRegistry:
    return SensorRegistry(buffer_frames=8, clock_step_ns=S, max_wait_ns=S // 5, capacity=capacity)


def test_a_declared_sensor_is_in_use_before_its_first_frame_and_timed_by_its_fps() -> None:
    reg = _registry()
    reg.declare(msgspec.structs.replace(info_for(Cam("p1", 0.0, 0.0)), fps=10.0))
    assert reg.in_use() == ["p1"] and reg.known() == ["p1"]
    assert reg.timing["p1"].declared_period_ns == S // 10
    reg.file(_frame("p1", 1, S), 0)
    reg.file(_frame("p1", 1, S), 0)  # a duplicate: counted, and offered to the timing
    assert reg.counters.duplicate == 1 and reg.timing["p1"].received == 2 and reg.received == 2


def test_a_sensor_that_went_is_forgotten_once_and_its_late_frames_are_dropped() -> None:
    reg = _registry()
    reg.declare(info_for(Cam("p1", 0.0, 0.0)))
    reg.came("p1")
    reg.file(_frame("p1", 1, S), 0)
    assert reg.went("p1")
    assert "p1" not in reg.buffers and "p1" not in reg.timing
    assert reg.absent() == ["p1"] and reg.in_use() == [] and reg.alive() == set()
    assert "p1" in reg.infos  # what it is stays: it may come back
    reg.file(_frame("p1", 2, 2 * S), 0)
    assert reg.counters.dropped == 1 and "p1" not in reg.buffers
    assert not reg.went("nobody")  # never heard of: nothing to forget


def test_one_capacity_bounds_frames_and_liveliness() -> None:
    reg = _registry(capacity=2)
    for k in range(3):
        reg.file(_frame(f"s{k}", 1, S), 0)
    assert sorted(reg.buffers) == ["s0", "s1"] and reg.counters.dropped == 1
    for k in range(PRESENCE_PER_SENSOR * 2 + 5):
        reg.came(f"t{k}")
    assert len(reg.present) == PRESENCE_PER_SENSOR * 2
    reg.went("t0")
    reg.came("new")  # room is made by forgetting the sensors already gone
    assert reg.present["new"] and "t0" not in reg.present


def test_trim_forgets_a_stale_sensor_that_never_said_what_it_is() -> None:
    reg = _registry()
    reg.declare(info_for(Cam("p1", 0.0, 0.0)))
    reg.file(_frame("p1", 1, S), 0)
    reg.file(_frame("x9", 1, S), 0)
    reg.trim(keep_from_ns=5 * S, forget_before_ns=4 * S)
    assert sorted(reg.buffers) == ["p1"] and "x9" not in reg.timing
