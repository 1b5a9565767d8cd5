"""Scoring and plotting a recording: a constant offset, tracks beside the ground truth, mobile cameras drawn, lost
TrackSets not scored but a silent manager's frames are."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import cv2
import pytest

from common.codec import encode
from common.schema import Pose, TrackSet
from tests.unit.user_agent.recorded_run import EPOCH, FPS, K, person, track
from user_agent.groundtruth import read_gt_csv
from user_agent.record import McapSink
from user_agent.recording import load_recording
from user_agent.report import plot_recording, score_recording


def test_score_of_recording_with_constant_offset(recorded: tuple[Path, Path]) -> None:
    mcap, gt_path = recorded
    scored = score_recording(load_recording(mcap), read_gt_csv(gt_path), threshold_m=0.5)
    m = scored.metrics
    assert scored.tracks_published == 2
    # Every frame from the first is scored, up to the last TrackSet (4.35 s) plus the 0.25 s gap: frames 1..47
    # ((k - 1) / 10 s). Frames 1 and 2 come before the first TrackSet (0.4 s) by more than the gap: both people
    # are missed there; from frame 3 on, both are tracked.
    assert scored.frames_scored == 47
    assert m.misses == 4 and m.false_positives == 0 and m.id_switches == 0
    assert m.mota == pytest.approx(1 - 4 / 94)
    assert m.mean_error_m == pytest.approx(0.05, abs=0.01)
    # The recording's warm-up end (its score_from_ns) is where scoring starts, when it has one.
    late = score_recording(load_recording(mcap), read_gt_csv(gt_path), start_ns=EPOCH + int(0.2e9))
    assert late.frames_scored == 47 - 3 + 1 and late.metrics.mota == 1.0 and late.metrics.idf1 == 1.0


def test_plot_draws_tracks_and_ground_truth_side_by_side(recorded: tuple[Path, Path], tmp_path: Path) -> None:
    mcap, gt_path = recorded
    out = plot_recording(mcap, tmp_path / "top.png", gt_path)
    img = cv2.imread(str(out))
    assert img is not None and img.shape[1] > 1.8 * img.shape[0] * (6 / 8) * 0.9
    # Coloured (non-grey) pixels exist in both halves: the tracks and the ground-truth paths.
    sat = cv2.cvtColor(img, cv2.COLOR_BGR2HSV)[:, :, 1]
    half = img.shape[1] // 2
    assert (sat[:, :half] > 120).sum() > 200 and (sat[:, half:] > 120).sum() > 200


def test_mobile_cameras_placed_by_mutual_calibration_are_collected_and_drawn(tmp_path: Path) -> None:
    from common.schema import ManagerStatus
    from common.schema import PoseEstimate as WirePose

    sink = McapSink(tmp_path / "m.mcap", {"epoch_ns": str(EPOCH), "fps": str(FPS), "room_x_m": "8", "room_y_m": "6"})
    for i in range(5):
        poses = [
            WirePose(sensor_id="pano1", pose=Pose(x_m=1.0, y_m=1.0, z_m=1.1, yaw_rad=0.0), source="surveyed"),
            WirePose(sensor_id="pano2", pose=Pose(x_m=2.0 + i, y_m=3.0, z_m=1.1, yaw_rad=0.0), source="mutual"),
        ]
        ms = ManagerStatus(manager_id="mgr1", seq=i, stamp_ns=EPOCH + i, tick_ms=1.0, tick_p99_ms=2.0,
                           tick_rate_hz=10.0, poses=poses)  # fmt: skip
        sink.write(K.manager_status("mgr1"), encode(ms), EPOCH + i)
    sink.close()
    rec = load_recording(tmp_path / "m.mcap")
    assert rec.mutual_paths == {"pano2": [(2.0 + i, 3.0) for i in range(5)]}  # surveyed poses are not paths
    with_path = cv2.imread(str(plot_recording(load_recording(tmp_path / "m.mcap"), tmp_path / "a.png")))
    rec.mutual_paths.clear()
    without = cv2.imread(str(plot_recording(rec, tmp_path / "b.png")))
    assert with_path is not None and without is not None
    assert (with_path != without).any()  # the mobile camera's path and body are drawn


def test_lost_tracksets_are_not_scored_but_a_silent_manager_is(recorded: tuple[Path, Path], tmp_path: Path) -> None:
    """Frames where the recording lost TrackSets (a gap in their seq) are skipped, not counted as misses;
    frames where the manager published nothing (no gap: it was silent) are scored."""
    _, gt_path = recorded
    gt = read_gt_csv(gt_path)

    def run(name: str, keep: Callable[[int], bool], seq: Callable[[int], int]) -> Any:
        sink = McapSink(tmp_path / name, {"epoch_ns": str(EPOCH), "fps": str(FPS)})
        for i in range(80):
            if not keep(i):
                continue
            stamp = EPOCH + int(0.4e9) + i * 50_000_000
            k = 1 + (stamp - EPOCH) / 1e9 * FPS
            tracks = [track(f"mgr1-{p + 1}", *person(k, p), stamp) for p in (0, 1)]
            ts = TrackSet(manager_id="mgr1", seq=seq(i), stamp_ns=stamp, tracks=tracks)
            sink.write(K.tracks(), encode(ts), stamp)
        sink.close()
        return score_recording(load_recording(tmp_path / name), gt)

    lost = run("lost.mcap", lambda i: not 20 <= i < 50, lambda i: i)  # 1.5 s of TrackSets the recorder lost
    silent = run("silent.mcap", lambda i: not 20 <= i < 50, lambda i: i if i < 20 else i - 30)  # manager silent
    assert lost.unseen_s == pytest.approx(1.05, abs=0.06) and silent.unseen_s == 0.0
    # Frames 1 and 2 come before the first TrackSet (both people missed there); the lost span costs nothing.
    assert lost.metrics.misses == 4 and lost.metrics.false_positives == 0
    assert silent.metrics.misses > 4 and silent.frames_scored > lost.frames_scored


def test_a_recording_without_its_epoch_is_lined_up_with_the_ground_truth_when_told(
    recorded: tuple[Path, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import user_agent.report as report

    mcap, gt_path = recorded
    rec = load_recording(mcap)
    rec.metadata.pop("epoch_ns")
    rec.metadata.pop("fps")
    seen: list[Any] = []
    monkeypatch.setattr(report, "save_top_view", lambda inp, out: seen.append(inp) or Path(out))
    plot_recording(rec, tmp_path / "a.png", gt_path)
    plot_recording(rec, tmp_path / "b.png", gt_path, epoch_ns=EPOCH, fps=FPS)
    assert (seen[0].epoch_ns, seen[0].fps) == (None, None)  # the timeline then has a row per track
    assert (seen[1].epoch_ns, seen[1].fps) == (EPOCH, FPS)
