"""ManagerStatus of one status period: tick statistics, inbox and gate counts, the latency split's medians."""

from __future__ import annotations

import pytest

from common.schema import Latency, ManagerStatus
from resource_manager.ingest.gate import SenderGate
from resource_manager.ingest.schedule import ScheduleParams, Scheduler
from resource_manager.serve.status import InboxCounts, manager_status


def _latency(age_ms: float, node_ms: float) -> Latency:
    return Latency(
        age_ms=age_ms,
        age_p50_ms=0.0,
        age_p99_ms=0.0,
        node_ms=node_ms,
        transport_ms=1.0,
        wait_ms=2.0,
        fusion_ms=3.0,
        publish_ms=0.5,
    )


def _status(tick_ms: list[float], latencies: list[Latency]) -> ManagerStatus:
    gate = SenderGate.of(["p2", "p1"], max_skew_ns=1_000_000_000)
    gate.refuse_unlisted("intruder", 3)
    schedule = Scheduler(ScheduleParams(mode="watermark", max_wait_ns=100_000_000, min_interval_ns=0))
    return manager_status(
        "mgr1",
        7,
        123,
        tick_ms=tick_ms,
        tick_cpu_ms=[0.5 * ms for ms in tick_ms],
        period_s=2.0,
        result=None,
        known=["p1"],
        inboxes=InboxCounts(decode_errors=4, dropped=5),
        gate=gate,
        refused_partial=False,
        schedule=schedule,
        frames_received=0,
        latencies=latencies,
    )


def test_status_of_a_period_with_ticks_and_published_tracksets() -> None:
    st = _status([10.0, 20.0, 30.0, 40.0], [_latency(100.0, 10.0), _latency(50.0, 30.0), _latency(80.0, 20.0)])
    assert (st.manager_id, st.seq, st.stamp_ns) == ("mgr1", 7, 123)
    assert st.tick_ms == pytest.approx(25.0) and st.tick_rate_hz == pytest.approx(2.0)
    assert st.tick_cpu_ms == pytest.approx(12.5)  # the fusing thread's own CPU time, apart from the wall clock's
    assert 39.0 < st.tick_p99_ms <= 40.0
    assert st.decode_errors == 4 and st.dropped_msgs == 5 and st.tracks == 0
    assert st.sensors_expected == ["p1", "p2"] and st.refused_msgs == 3
    assert st.sensors_known == ["p1"]  # heard of before any fusion (what the demo waits for before it starts)
    assert st.schedule == "watermark" and st.timing == []
    assert st.latency is not None
    assert st.latency.age_ms == 80.0  # the newest TrackSet's age
    assert st.latency.age_p50_ms == 80.0 and st.latency.node_ms == 20.0  # medians
    assert st.latency.fusion_ms == 3.0


def test_status_of_an_idle_period() -> None:
    st = _status([], [])
    assert st.tick_ms == 0.0 and st.tick_cpu_ms == 0.0 and st.tick_rate_hz == 0.0 and st.latency is None
    assert st.sensors_in_use == [] and st.poses == []
