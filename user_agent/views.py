"""Text views for the terminal: the live ``watch`` screen and the ``tracks``/``history`` tables.

Pure formatting (no zenoh): data in, a string out; the CLI prints it.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence

from common.schema import Latency, Track
from user_agent.client import ManagerView, SensorView

__all__ = [
    "CLEAR_SCREEN",
    "agreement_lines",
    "format_table",
    "history_table",
    "latency_lines",
    "refused_lines",
    "tracks_table",
    "watch_screen",
]

CLEAR_SCREEN = "\x1b[H\x1b[2J"


def format_table(headers: Sequence[str], rows: Iterable[Sequence[object]]) -> str:
    """Left-aligned text columns, two spaces apart."""
    cells = [[str(h) for h in headers]] + [[str(c) for c in r] for r in rows]
    widths = [max(len(r[i]) for r in cells) for i in range(len(headers))]
    lines = ["  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip() for r in cells]
    lines.insert(1, "  ".join("-" * w for w in widths))
    return "\n".join(lines)


def _pair(t: Track) -> str:
    return "+".join(t.sensors) if t.sensors else "-"


def tracks_table(tracks: Sequence[Track]) -> str:
    """Current tracks: id, state, position, height, speed, the pair that localised it and its predicted error."""
    rows = [
        (
            t.track_id,
            t.state,
            f"{t.x_m:7.2f}",
            f"{t.y_m:7.2f}",
            f"{t.height_m:4.2f}" if t.height_m > 0 else "  - ",
            f"{math.hypot(t.vx_mps, t.vy_mps):4.2f}",
            _pair(t),
            t.method,
            f"{t.predicted_error_m:5.3f}",
            f"{t.age_s:6.1f}",
        )
        for t in tracks
    ]
    heads = ("track", "state", "x_m", "y_m", "h_m", "v_mps", "pair", "method", "pred_err_m", "age_s")
    return format_table(heads, rows)


def history_table(path: Sequence[Track]) -> str:
    """A track's path: one row per state."""
    if not path:
        return "(no history)"
    t0 = path[0].stamp_ns
    rows = [
        (f"{(t.stamp_ns - t0) / 1e9:7.2f}", f"{t.x_m:7.2f}", f"{t.y_m:7.2f}", f"{t.height_m:4.2f}", t.state, _pair(t))
        for t in path
    ]
    return format_table(("t_s", "x_m", "y_m", "h_m", "state", "pair"), rows)


def _sensors_table(sensors: Sequence[SensorView], fused: set[str] | None = None) -> str:
    rows = []
    for s in sensors:
        st, info = s.status, s.info
        live = "up" if s.alive else "DOWN"
        if fused is not None and s.sensor_id not in fused:
            live += " (not fused)"
        rows.append(
            (
                s.sensor_id,
                live,
                info.kind if info else "?",
                (info.pose_source if info else "?"),
                f"{st.fps:5.1f}" if st else "-",
                st.frames if st else "-",
                st.dropped_frames if st else "-",
                f"{st.processing_ms:5.1f}" if st else "-",
                f"{s.clock_offset_ns / 1e6:+7.2f}",
                (st.clock_source if st else (info.clock_source if info else "?")),
                st.source_state if st else "-",
                st.decode_errors if st else "-",
            )
        )
    heads = (
        "sensor",
        "live",
        "kind",
        "pose",
        "fps",
        "frames",
        "drops",
        "proc_ms",
        "clock_ms",
        "clock",
        "source",
        "bad",
    )
    return format_table(heads, rows)


def _fused(managers: Sequence[ManagerView]) -> set[str] | None:
    """The sensors some live manager fuses (None: unknown, or one accepts any sensor)."""
    lists = [m.status.sensors_expected for m in managers if m.alive and m.status is not None]
    if not lists or any(not ids for ids in lists):
        return None
    return {sid for ids in lists for sid in ids}


def _managers_table(managers: Sequence[ManagerView]) -> str:
    rows = []
    for m in managers:
        st = m.status
        rows.append(
            (
                m.manager_id,
                "up" if m.alive else "DOWN",
                f"{st.role}:{st.zone}" if st and st.zone else "-",
                f"{st.tick_ms:6.2f}" if st else "-",
                f"{st.tick_p99_ms:6.2f}" if st else "-",
                f"{st.tick_rate_hz:5.1f}" if st else "-",
                _age(st.latency) if st else "-",
                st.tracks if st else "-",
                ",".join(st.sensors_in_use) if st else "-",
                ",".join(st.sensors_without_pose) if st and st.sensors_without_pose else "-",
                (st.late_msgs + st.out_of_order_msgs + st.duplicate_msgs) if st else "-",
                st.decode_errors if st else "-",
            )
        )
    heads = (
        "manager",
        "live",
        "role",
        "tick_ms",
        "p99_ms",
        "hz",
        "age_ms",
        "tracks",
        "sensors in use",
        "no pose",
        "late/ooo",
        "bad",
    )
    return format_table(heads, rows)


def _age(lat: Latency | None) -> str:
    """Capture -> publish age of the newest TrackSet (and the period's p99)."""
    return "-" if lat is None else f"{lat.age_ms:.0f} (p99 {lat.age_p99_ms:.0f})"


def latency_lines(managers: Sequence[ManagerView]) -> list[str]:
    """The LATENCY section: where each manager's capture -> publish time went, and each sensor's frame timing."""
    split = [
        (
            m.manager_id,
            m.status.schedule,
            f"{lat.age_p50_ms:6.1f}",
            f"{lat.age_p99_ms:6.1f}",
            f"{lat.node_ms:6.1f}",
            f"{lat.transport_ms:6.1f}",
            f"{lat.wait_ms:6.1f}",
            f"{lat.fusion_ms:6.1f}",
            f"{lat.publish_ms:6.1f}",
        )
        for m in managers
        if m.status is not None and (lat := m.status.latency) is not None
    ]
    timing = [
        (
            t.sensor_id,
            m.manager_id,
            f"{t.period_ms:6.1f}",
            f"{t.delay_ms:6.1f}",
            f"{t.jitter_ms:6.1f}",
            f"{t.wait_ms:6.1f}",
            t.late_frames,
            t.missed,
        )
        for m in managers
        if m.status is not None
        for t in m.status.timing
    ]
    if not split and not timing:
        return []
    out = ["", "LATENCY (capture -> publish, ms, medians over the last status period)"]
    if split:
        heads: tuple[str, ...] = ("manager", "schedule", "p50", "p99", "node", "transport", "wait", "fusion", "publish")
        out.append(format_table(heads, split))
    if timing:
        out.append("")
        heads = ("sensor", "manager", "period_ms", "delay_ms", "jitter_ms", "waited_ms", "late", "missed")
        out.append(format_table(heads, timing))
    return out


def _poses_table(managers: Sequence[ManagerView]) -> str:
    rows = [
        (
            e.sensor_id,
            e.source,
            f"{e.pose.x_m:7.2f}",
            f"{e.pose.y_m:7.2f}",
            f"{math.degrees(e.pose.yaw_rad):7.1f}",
            f"{e.sigma_m:5.3f}",
            m.manager_id,
        )
        for m in managers
        if m.status is not None
        for e in m.status.poses
    ]
    return format_table(("sensor", "pose", "x_m", "y_m", "yaw_deg", "sigma_m", "manager"), rows)


def agreement_lines(managers: Sequence[ManagerView]) -> list[str]:
    """The CAMERA AGREEMENT section: per camera, how far its blobs fall from the people the others see; a camera
    that disagrees (bumped or moved) is marked, with what to do (empty before any manager measured one)."""
    rows = [
        (
            a.sensor_id,
            f"{a.residual_m:6.2f}",
            "-" if a.settled_m is None else f"{a.settled_m:6.2f}",
            a.blobs,
            f"{100 * a.unexplained_frac:5.1f}",
            "DISAGREES" if a.disagrees else "ok",
            m.manager_id,
        )
        for m in managers
        if m.status is not None
        for a in m.status.agreement
    ]
    if not rows:
        return []
    out = [
        "",
        "CAMERA AGREEMENT (median distance of each camera's blobs from the people the others place; in_place_m: "
        "its own, learned while it agreed)",
    ]
    out.append(format_table(("sensor", "residual_m", "in_place_m", "blobs", "unexplained_%", "state", "manager"), rows))
    if any(r[5] == "DISAGREES" for r in rows):
        out.append(
            "a camera that disagrees was bumped or moved: record the site (agent record) while people walk, then "
            "panostereo calib refine SITE --recording REC.mcap --fix <cameras still in place> --out DIR"
        )
    return out


def _refused_table(managers: Sequence[ManagerView], most: int = 10) -> str:
    rows = [
        (m.manager_id, r.sender_id, r.unlisted, r.wrong_id, r.skewed, r.ahead, r.sighting)
        for m in managers
        if m.status is not None
        for r in m.status.refused[:most]
    ]
    return format_table(("manager", "sender", "not fused", "wrong id", "late", "ahead", "sightings"), rows)


def refused_lines(managers: Sequence[ManagerView]) -> list[str]:
    """The REFUSED section: who sent what the managers would not take (empty when nobody did)."""
    seen = [m for m in managers if m.status is not None and m.status.refused_msgs]
    if not seen:
        return []
    total = sum(m.status.refused_msgs for m in seen if m.status is not None)
    partial = any(m.status is not None and m.status.refused_partial for m in seen)
    head = f"REFUSED ({total} messages{'; a flood paused counting: at least' if partial else ''})"
    return ["", head, _refused_table(seen)]


def watch_screen(
    tracks: Sequence[Track],
    sensors: Sequence[SensorView],
    managers: Sequence[ManagerView],
    header: str = "",
    footer: Sequence[str] = (),
) -> str:
    """The whole live screen (``footer``: extra lines, e.g. a recorder's lag and drops)."""
    parts = []
    if header:
        parts.append(header)
    parts.append(f"TRACKS ({len(tracks)})")
    parts.append(tracks_table(tracks) if tracks else "(none)")
    parts.append("")
    parts.append(f"SENSORS ({sum(s.alive for s in sensors)} up of {len(sensors)})")
    parts.append(_sensors_table(sensors, _fused(managers)) if sensors else "(none)")
    parts.append("")
    parts.append("MANAGERS")
    parts.append(_managers_table(managers) if managers else "(none)")
    if any(m.status is not None and m.status.poses for m in managers):
        parts.append("")
        parts.append("CAMERA POSES (where the manager places each camera: surveyed, or mutual calibration)")
        parts.append(_poses_table(managers))
    parts += agreement_lines(managers)
    parts += latency_lines(managers)
    parts += refused_lines(managers)
    parts += list(footer)
    return "\n".join(parts) + "\n"
