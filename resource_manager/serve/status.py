"""ManagerStatus from one status period: tick times, the last tick's counters, the inboxes' and the gate's counts."""

from __future__ import annotations

from collections.abc import Collection, Sequence
from dataclasses import dataclass

import numpy as np

from common.angles import wrap_angle
from common.schema import MAX_SENSORS, Latency, ManagerStatus, Pose, SensorTiming
from common.schema import PoseEstimate as WirePoseEstimate
from resource_manager.fusion import TickResult
from resource_manager.ingest.gate import SenderGate
from resource_manager.ingest.schedule import Scheduler

__all__ = ["InboxCounts", "manager_status"]


@dataclass(frozen=True, slots=True)
class InboxCounts:
    """What the shell's subscriptions and queryables saw over the run."""

    decode_errors: int
    dropped: int


def manager_status(
    manager_id: str,
    seq: int,
    stamp_ns: int,
    *,
    tick_ms: Sequence[float],
    tick_cpu_ms: Sequence[float],
    period_s: float,
    result: TickResult | None,
    known: Sequence[str],
    inboxes: InboxCounts,
    gate: SenderGate,
    refused_partial: bool,
    schedule: Scheduler,
    frames_received: int,
    latencies: Collection[Latency],
) -> ManagerStatus:
    """The status message; lists are capped at their schema bounds. ``known``: the sensors heard of now (before
    the first fusion too). ``latencies``: the capture -> publish split of each TrackSet published in the period,
    oldest first. ``frames_received``: every Features message offered to the sensor registry so far."""
    ms = np.asarray(list(tick_ms) or [0.0])
    c = result.counters if result is not None else None
    refusals = gate.refusals
    return ManagerStatus(
        manager_id=manager_id,
        seq=seq,
        stamp_ns=stamp_ns,
        tick_ms=float(ms.mean()),
        tick_p99_ms=float(np.percentile(ms, 99)),
        tick_rate_hz=len(tick_ms) / period_s,
        tick_cpu_ms=float(np.mean(tick_cpu_ms)) if len(tick_cpu_ms) else 0.0,
        sensors_in_use=(c.sensors_in_use if c else [])[:MAX_SENSORS],
        sensors_known=list(known)[:MAX_SENSORS],
        sensors_without_pose=(c.sensors_without_pose if c else [])[:MAX_SENSORS],
        tracks=len(result.trackset.tracks) if result and result.trackset else 0,
        decode_errors=inboxes.decode_errors,
        late_msgs=c.late if c else 0,
        duplicate_msgs=c.duplicate if c else 0,
        out_of_order_msgs=c.out_of_order if c else 0,
        dropped_msgs=inboxes.dropped + (c.dropped if c else 0),
        sensors_absent=(c.sensors_absent if c else [])[:MAX_SENSORS],
        poses=[
            WirePoseEstimate(
                sensor_id=p.sensor_id,
                pose=Pose(x_m=p.x_m, y_m=p.y_m, z_m=p.z_m, yaw_rad=wrap_angle(p.yaw_rad)),
                source=p.source,
                sigma_m=p.sigma_xy_m,
            )
            for p in (c.poses if c else ())[:MAX_SENSORS]
        ],
        sensors_expected=gate.expected[:MAX_SENSORS],
        refused_msgs=refusals.total,
        refused=refusals.top(MAX_SENSORS),
        refused_partial=refused_partial,
        schedule=schedule.params.mode,
        frames_received=frames_received,
        latency=_latency(latencies),
        timing=_timing(schedule)[:MAX_SENSORS],
    )


def _latency(latencies: Collection[Latency]) -> Latency | None:
    """Medians of each part over the period; the newest TrackSet's age, and the ages' p50 and p99."""
    if not latencies:
        return None
    rows = np.array(
        [(x.age_ms, x.node_ms, x.transport_ms, x.wait_ms, x.fusion_ms, x.publish_ms) for x in latencies], float
    )
    med = np.median(rows, axis=0)
    return Latency(
        age_ms=float(rows[-1, 0]),
        age_p50_ms=float(med[0]),
        age_p99_ms=float(np.percentile(rows[:, 0], 99)),
        node_ms=float(med[1]),
        transport_ms=float(med[2]),
        wait_ms=float(med[3]),
        fusion_ms=float(med[4]),
        publish_ms=float(med[5]),
    )


def _timing(schedule: Scheduler) -> list[SensorTiming]:
    wait = schedule.params.max_wait_ns
    return [
        SensorTiming(
            sensor_id=sid,
            period_ms=s.period() / 1e6,
            delay_ms=s.delay_ns / 1e6,
            jitter_ms=(s.delay_dev_ns + s.period_dev_ns) / 1e6,
            wait_ms=s.allowance_ns(wait) / 1e6 if schedule.params.mode == "watermark" else wait / 1e6,
            frames=s.received,
            late_frames=s.late,
            missed=s.missed,
        )
        for sid, s in sorted(schedule.sensors.items())
        if s.frames
    ]
