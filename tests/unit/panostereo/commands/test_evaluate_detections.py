"""`panostereo evaluate-detections` on a small recording: one sensor's blobs scored against ground-truth boxes
from the frames after --skip-s; a recording it cannot score is refused naming why."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from common.codec import encode
from common.keys import Keys
from common.schema import Blob, Features, PinholeModel, SensorInfo
from panostereo.cli import main
from user_agent.record import McapSink

EPOCH = 1_700_000_000_000_000_000
PERIOD_NS = 200_000_000
"""5 frames per second."""
FRAMES = 10
MISSED = 7
"""0-based frame in which the detector reported nothing."""
K = Keys("pano")


def _box(k: int) -> tuple[float, float, float, float]:
    """Ground truth of 0-based frame k: one person walking right (left, top, width, height)."""
    return (100.0 + 10.0 * k, 50.0, 40.0, 120.0)


def _blob(k: int) -> Blob:
    left, top, w, h = _box(k)
    # Blob boxes are whole pixels with centres on integers: the edges are half a pixel beyond them.
    return Blob(local_id=1, bearing_rad=0.1, width_rad=0.05, top_elev_rad=0.1, bottom_elev_rad=-0.3,
                bbox_u_px=left + 0.5, bbox_v_px=top + 0.5, bbox_w_px=w, bbox_h_px=h)  # fmt: skip


def _recording(tmp_path: Path, sensors: tuple[str, ...] = ("c1",)) -> Path:
    sink = McapSink(tmp_path / "run.mcap", {"prefix": "pano"}, foxglove=False)
    model = PinholeModel(width_px=640, height_px=480, k=[500.0, 0.0, 320.0, 0.0, 500.0, 240.0, 0.0, 0.0, 1.0])
    for sid in sensors:
        info = SensorInfo(sensor_id=sid, seq=0, stamp_ns=EPOCH, kind="pinhole", model=model)
        sink.write(K.sensor_info(sid), encode(info), EPOCH)
        for k in range(FRAMES):
            stamp = EPOCH + k * PERIOD_NS
            blobs = [] if k == MISSED else [_blob(k)]
            feat = Features(sensor_id=sid, seq=k, stamp_ns=stamp, frame_index=k, blobs=blobs,
                            state="ok" if k >= 1 else "learning")  # fmt: skip
            sink.write(K.sensor_features(sid), encode(feat), stamp + 1)
    sink.close()
    return tmp_path / "run.mcap"


def _truth(tmp_path: Path) -> Path:
    path = tmp_path / "gt.txt"
    path.write_text("".join(f"{k + 1},1,{','.join(str(v) for v in _box(k))},1,-1,-1,-1\n" for k in range(FRAMES)))
    return path


def _evaluate(capsys: pytest.CaptureFixture[str], *args: str) -> dict[str, Any]:
    assert main(["evaluate-detections", *args, "--json"]) == 0
    result: dict[str, Any] = json.loads(capsys.readouterr().out)
    return result


def test_a_recordings_blobs_are_scored_against_the_boxes_after_the_skip(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    mcap, truth = _recording(tmp_path), _truth(tmp_path)
    result = _evaluate(capsys, str(mcap), "--ground-truth", str(truth), "--skip-s", "0.4")
    assert (result["frames"], result["scored_frames"]) == (FRAMES, FRAMES - 2)  # from 0.4 s: frames 3..10
    assert result["first_reported_frame"] == 2 and result["startup_s"] == pytest.approx(0.2)
    scored = result["iou_0.5"]
    assert (scored["objects"], scored["matches"], scored["misses"], scored["false_positives"]) == (8, 7, 1, 0)
    assert scored["recall"] == pytest.approx(7 / 8) and scored["precision"] == 1.0
    everything = _evaluate(capsys, str(mcap), "--ground-truth", str(truth), "--skip-s", "0")
    assert everything["scored_frames"] == FRAMES and everything["iou_0.5"]["matches"] == FRAMES - 1


def test_with_several_sensors_one_must_be_chosen(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    mcap, truth = _recording(tmp_path, ("c1", "c2")), _truth(tmp_path)
    assert main(["evaluate-detections", str(mcap), "--ground-truth", str(truth)]) == 1
    assert "several sensors (c1, c2): choose one with --sensor" in capsys.readouterr().err
    assert _evaluate(capsys, str(mcap), "--ground-truth", str(truth), "--sensor", "c2")["frames"] == FRAMES
    assert main(["evaluate-detections", str(mcap), "--ground-truth", str(truth), "--sensor", "c9"]) == 1
    assert "'c9' has no Features" in capsys.readouterr().err


def test_a_missing_source_or_a_video_without_calibration_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    truth = _truth(tmp_path)
    assert main(["evaluate-detections", str(tmp_path / "none.mcap"), "--ground-truth", str(truth)]) == 1
    assert "no such file" in capsys.readouterr().err
    video = tmp_path / "clip.avi"
    video.write_bytes(b"\0" * 16)
    assert main(["evaluate-detections", str(video), "--ground-truth", str(truth)]) == 1
    err = capsys.readouterr().err
    assert "needs --calibration" in err and err.count("evaluate-detections") == 1  # the prefix once, not twice


@pytest.mark.parametrize("fps", ["0", "-1", "inf", "nan", "seven"])
def test_a_rate_that_is_not_a_positive_number_is_refused_where_it_enters(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], fps: str
) -> None:
    with pytest.raises(SystemExit) as stop:
        main(["evaluate-detections", str(_recording(tmp_path)), "--ground-truth", str(_truth(tmp_path)), "--fps", fps])
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert "argument --fps:" in err and "Traceback" not in err


def _video(tmp_path: Path, fps: float) -> tuple[Path, Path]:
    import cv2
    import numpy as np

    path = tmp_path / "clip.avi"
    out = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), fps, (320, 240))
    for k in range(12):
        img = np.full((240, 320, 3), 120, np.uint8)
        cv2.rectangle(img, (40 + 10 * k, 60), (70 + 10 * k, 180), (20, 20, 20), -1)
        out.write(img)
    out.release()
    calib = tmp_path / "cam.json"
    calib.write_text(json.dumps({"model": "pinhole", "image_size": [320, 240],
                                 "K": [[300, 0, 160], [0, 300, 120], [0, 0, 1]], "dist": [],
                                 "R": [[1, 0, 0], [0, 0, -1], [0, 1, 0]], "t": [0, 1.5, 0]}))  # fmt: skip
    return path, calib


@pytest.mark.parametrize(
    ("given", "want"), [([], "played at 10 fps (from the file)"), (["--fps", "4"], "played at 4 fps (from --fps)")]
)
def test_a_video_s_rate_is_printed_with_where_it_came_from(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], given: list[str], want: str
) -> None:
    video, calib = _video(tmp_path, 10.0)
    args = ["evaluate-detections", str(video), "--ground-truth", str(_truth(tmp_path)), "--calibration", str(calib)]
    assert main([*args, "--skip-s", "0", *given]) == 0
    assert want in capsys.readouterr().out
