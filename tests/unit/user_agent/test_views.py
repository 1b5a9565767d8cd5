"""Terminal views: the columns a user reads."""

from __future__ import annotations

import math

import msgspec

from common.schema import ManagerStatus, NodeStatus, Track
from user_agent.client import ManagerView, SensorView
from user_agent.views import format_table, history_table, tracks_table, watch_screen


def _track(tid: str, stamp: int, sensors: list[str]) -> Track:
    return Track(manager_id="m", seq=0, stamp_ns=stamp, track_id=tid, x_m=1.25, y_m=-2.5, height_m=1.78, vx_mps=0.3,
                 vy_mps=0.4, cov_xx_m2=0.0, cov_xy_m2=0.0, cov_yy_m2=0.0, state="confirmed", method="size_ratio",
                 sensors=sensors, predicted_error_m=0.123)  # fmt: skip


def test_format_table_aligns_columns() -> None:
    text = format_table(("a", "bbb"), [(1, "x"), ("long", "y")])
    lines = text.splitlines()
    assert lines[0] == "a     bbb" and lines[1] == "----  ---" and lines[3] == "long  y"


def test_tracks_table_shows_position_height_speed_pair_and_predicted_error() -> None:
    row = tracks_table([_track("m-1", 0, ["pano1", "pano2"])]).splitlines()[2].split()
    assert row == ["m-1", "confirmed", "1.25", "-2.50", "1.78", "0.50", "pano1+pano2", "size_ratio", "0.123", "0.0"]


def test_history_table_is_relative_to_the_first_state() -> None:
    text = history_table([_track("m-1", 10**18, []), _track("m-1", 10**18 + 500_000_000, ["a", "b"])])
    assert [ln.split()[0] for ln in text.splitlines()[2:]] == ["0.00", "0.50"]
    assert history_table([]) == "(no history)"


def test_watch_screen_has_sensor_fps_drops_clock_and_manager_tick() -> None:
    st = NodeStatus(sensor_id="pano1", seq=1, stamp_ns=1, fps=14.9, frames=300, dropped_frames=7, processing_ms=9.5,
                    clock_offset_ns=-1_250_000, clock_uncertainty_ns=10, clock_source="ntp", decode_errors=0,
                    source_state="ok")  # fmt: skip
    ms = ManagerStatus(manager_id="mgr1", seq=1, stamp_ns=1, tick_ms=2.5, tick_p99_ms=4.0, tick_rate_hz=10.0,
                       sensors_in_use=["pano1"], tracks=1)  # fmt: skip
    text = watch_screen(
        [_track("mgr1-1", 0, [])], [SensorView("pano1", True, None, st)], [ManagerView("mgr1", True, ms)], "hdr"
    )
    sensor_row = next(ln for ln in text.splitlines() if ln.startswith("pano1"))
    assert sensor_row.split()[4:9] == ["14.9", "300", "7", "9.5", "-1.25"]
    mgr_row = next(ln for ln in text.splitlines() if ln.startswith("mgr1 "))
    assert mgr_row.split()[:6] == ["mgr1", "up", "-", "2.50", "4.00", "10.0"]
    assert text.startswith("hdr\nTRACKS (1)")


def test_watch_screen_shows_each_zone_managers_role() -> None:
    lead = ManagerStatus(manager_id="hall-a", seq=1, stamp_ns=1, tick_ms=2.5, tick_p99_ms=4.0, tick_rate_hz=10.0,
                         zone="hall", role="leader", leader_id="hall-a")  # fmt: skip
    stand = msgspec.structs.replace(lead, manager_id="hall-b", role="standby")
    text = watch_screen([], [], [ManagerView("hall-a", True, lead), ManagerView("hall-b", True, stand)])
    rows = {ln.split()[0]: ln.split()[:3] for ln in text.splitlines() if ln.startswith("hall-")}
    assert rows == {"hall-a": ["hall-a", "up", "leader:hall"], "hall-b": ["hall-b", "up", "standby:hall"]}


def test_watch_screen_lists_the_camera_poses_the_manager_knows() -> None:
    from common.schema import Pose, PoseEstimate

    est = PoseEstimate(sensor_id="robot1", pose=Pose(x_m=3.25, y_m=2.5, z_m=1.1, yaw_rad=math.pi / 2),
                       source="mutual", sigma_m=0.042)  # fmt: skip
    ms = ManagerStatus(manager_id="mgr1", seq=1, stamp_ns=1, tick_ms=2.5, tick_p99_ms=4.0, tick_rate_hz=10.0,
                       poses=[est])  # fmt: skip
    text = watch_screen([], [], [ManagerView("mgr1", True, ms)])
    row = next(ln for ln in text.splitlines() if ln.startswith("robot1"))
    assert row.split() == ["robot1", "mutual", "3.25", "2.50", "90.0", "0.042", "mgr1"]
    assert "CAMERA POSES" not in watch_screen([], [], [ManagerView("mgr1", True, None)])


def test_watch_screen_names_refused_senders_and_sensors_no_manager_fuses() -> None:
    from common.schema import Refusal

    refused = [Refusal(sender_id="evil", unlisted=1200), Refusal(sender_id="pano3", sighting=3)]
    ms = ManagerStatus(manager_id="mgr1", seq=1, stamp_ns=1, tick_ms=2.5, tick_p99_ms=4.0, tick_rate_hz=10.0,
                       sensors_expected=["pano1"], refused_msgs=1203, refused_partial=True,
                       refused=refused)  # fmt: skip
    sensors = [SensorView("pano1", True, None, None), SensorView("stray", True, None, None)]
    text = watch_screen([], sensors, [ManagerView("mgr1", True, ms)], footer=["recording: nothing lost"])
    lines = text.splitlines()
    assert next(ln for ln in lines if ln.startswith("stray")).split()[1:4] == ["up", "(not", "fused)"]
    assert "(not fused)" not in next(ln for ln in lines if ln.startswith("pano1"))
    assert "REFUSED (1203 messages; a flood paused counting: at least)" in lines
    assert ["mgr1", "evil", "1200", "0", "0", "0", "0"] in [ln.split() for ln in lines]
    assert ["mgr1", "pano3", "0", "0", "0", "0", "3"] in [ln.split() for ln in lines]  # refused sightings
    assert lines[-1] == "recording: nothing lost"
    quiet = ManagerStatus(manager_id="mgr1", seq=1, stamp_ns=1, tick_ms=2.5, tick_p99_ms=4.0, tick_rate_hz=10.0)
    assert "REFUSED" not in watch_screen([], sensors, [ManagerView("mgr1", True, quiet)])


def test_watch_screen_shows_where_the_latency_went_and_each_sensors_timing() -> None:
    from common.schema import Latency, SensorTiming

    lat = Latency(age_ms=41.0, age_p50_ms=40.2, age_p99_ms=61.5, node_ms=3.1, transport_ms=0.7, wait_ms=28.0,
                  fusion_ms=8.4, publish_ms=0.2)  # fmt: skip
    timing = [SensorTiming(sensor_id="pano1", period_ms=33.3, delay_ms=4.2, jitter_ms=0.8, wait_ms=20.0, frames=900,
                           late_frames=2, missed=1)]  # fmt: skip
    ms = ManagerStatus(manager_id="mgr1", seq=1, stamp_ns=1, tick_ms=8.4, tick_p99_ms=9.0, tick_rate_hz=10.0,
                       latency=lat, timing=timing)  # fmt: skip
    lines = watch_screen([], [], [ManagerView("mgr1", True, ms)]).splitlines()
    mgr_row = next(ln for ln in lines if ln.startswith("mgr1 ") and "up" in ln)
    assert "41 (p99 62)" in mgr_row
    split = next(ln.split() for ln in lines if ln.startswith("mgr1 ") and "watermark" in ln)
    assert split == ["mgr1", "watermark", "40.2", "61.5", "3.1", "0.7", "28.0", "8.4", "0.2"]
    assert ["pano1", "mgr1", "33.3", "4.2", "0.8", "20.0", "2", "1"] in [ln.split() for ln in lines]
    quiet = ManagerStatus(manager_id="mgr1", seq=1, stamp_ns=1, tick_ms=2.5, tick_p99_ms=4.0, tick_rate_hz=10.0)
    assert not any(
        ln.startswith("LATENCY") for ln in watch_screen([], [], [ManagerView("mgr1", True, quiet)]).splitlines()
    )


def test_watch_screen_marks_a_camera_that_disagrees_and_says_how_to_fix_it() -> None:
    from common.schema import SensorAgreement

    agreement = [
        SensorAgreement(sensor_id="cam3", residual_m=0.83, blobs=120, unexplained_frac=0.25, disagrees=True),
        SensorAgreement(sensor_id="cam1", residual_m=0.07, blobs=300, settled_m=0.05),
    ]
    ms = ManagerStatus(manager_id="mgr1", seq=1, stamp_ns=1, tick_ms=2.5, tick_p99_ms=4.0, tick_rate_hz=10.0,
                       agreement=agreement)  # fmt: skip
    lines = watch_screen([], [], [ManagerView("mgr1", True, ms)]).splitlines()
    assert next(ln for ln in lines if ln.startswith("cam3")).split() == [
        "cam3",
        "0.83",
        "-",
        "120",
        "25.0",
        "DISAGREES",
        "mgr1",
    ]
    assert next(ln for ln in lines if ln.startswith("cam1")).split()[2:6] == ["0.05", "300", "0.0", "ok"]
    assert any("calib refine SITE --recording" in ln for ln in lines)
    plain = ManagerStatus(manager_id="mgr1", seq=1, stamp_ns=1, tick_ms=2.5, tick_p99_ms=4.0, tick_rate_hz=10.0)
    assert "CAMERA AGREEMENT" not in watch_screen([], [], [ManagerView("mgr1", True, plain)])
