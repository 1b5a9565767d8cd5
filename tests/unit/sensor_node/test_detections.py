"""Detection files: MOTChallenge parsing, calibration loading, boxes -> Features, real-time playback."""

from __future__ import annotations

import json
import math
import threading
from pathlib import Path

import numpy as np
import pytest

from common.cameras import PtzCamera
from common.codec import decode, encode
from common.errors import ConfigError, SourceError
from common.schema import Features
from sensor_node.detections import Detection, DetectionFrames, features_from_detections, load_calibration, read_mot
from sensor_node.tracks2d import Tracker2D


def test_read_mot(tmp_path: Path) -> None:
    p = tmp_path / "det.txt"
    p.write_text("# comment\n1,-1,10,20,30,60,0.9,-1,-1,-1\n1,4,100,20,30,60,0.3\n\n3,5,1.5,2.5,3,4,0.7,-1,-1,-1\n")
    dets = read_mot(p)
    assert sorted(dets) == [1, 3] and len(dets[1]) == 2 and dets[3][0].track_id == 5
    assert dets[3][0].left_px == 1.5
    assert len(read_mot(p, min_confidence=0.5)[1]) == 1


@pytest.mark.parametrize(
    ("line", "needle"),
    [("1,2,3", "expected 'frame,id,left,top,width,height,conf"), ("x,1,2,3,4,5,6", "det.txt:1"),
     ("0,1,2,3,4,5,0.5", "frame >= 1"), ("1,1,2,3,-4,5,0.5", "positive finite box")],
)  # fmt: skip
def test_read_mot_errors_name_file_and_line(tmp_path: Path, line: str, needle: str) -> None:
    p = tmp_path / "det.txt"
    p.write_text(line + "\n")
    with pytest.raises(SourceError, match=needle):
        read_mot(p)
    with pytest.raises(SourceError, match="cannot read"):
        read_mot(tmp_path / "none.txt")


def test_load_calibration(tmp_path: Path) -> None:
    p = tmp_path / "c.json"
    p.write_text(
        json.dumps(
            {"model": "pinhole", "image_size": [640, 480], "P": [[500, 0, 320, 0], [0, 500, 240, 0], [0, 0, 1, 0]]}
        )
    )
    cam = load_calibration(p)
    assert cam.width_px == 640
    p.write_text(json.dumps({"model": "fisheye"}))
    with pytest.raises(ConfigError, match="expected 'pinhole', got 'fisheye'"):
        load_calibration(p)
    p.write_text("{not json")
    with pytest.raises(ConfigError, match="invalid JSON"):
        load_calibration(p)


def test_boxes_to_world_azimuths() -> None:
    ptz = PtzCamera(0.0, 0.0, 2.0, 640, 480, math.radians(60), pan_rad=math.radians(90), tilt_rad=math.radians(-15))
    cam = ptz.pinhole()
    # A person at (0.5, 5): project feet and head top, make a box around them.
    (uf, vf), (_, vh) = cam.project(np.array([[0.5, 5.0, 0.0], [0.5, 5.0, 1.8]]))[0]
    dets = [Detection(1, 3, uf - 15, vh, 30, vf - vh, 0.8), Detection(1, -1, 10, 10, 20, 40, 1.5)]
    tracker = Tracker2D(0.05, 3, 2 * math.pi)
    f = features_from_detections(dets, cam, sensor_id="c1", seq=4, stamp_ns=123, frame_index=0, tracker=tracker)
    f = decode(encode(f), Features)
    a, b = f.blobs
    assert a.local_id == 3 and b.local_id >= 1_000_000  # the file's id, else the tracker's
    assert a.bearing_rad == pytest.approx(math.atan2(5.0, 0.5), abs=1e-6)
    assert a.top_elev_rad == pytest.approx(math.atan2(-0.2, math.hypot(0.5, 5.0)), abs=1e-4)
    assert a.bottom_elev_rad == pytest.approx(math.atan2(-2.0, math.hypot(0.5, 5.0)), abs=1e-6)
    corners, _ = cam.bearing_elevation(np.array([[uf - 15, vf], [uf + 15, vf]]))
    assert a.width_rad == pytest.approx(abs(corners[0] - corners[1]), abs=1e-9)
    assert a.width_rad == pytest.approx(2 * math.atan(15 / ptz.focal_px), rel=0.1)
    assert a.hist == [] and a.confidence == pytest.approx(0.8) and b.confidence == 1.0
    assert f.seq == 4 and f.stamp_ns == 123
    # Same untracked box next frame: same tracker id.
    f2 = features_from_detections([dets[1]], cam, sensor_id="c1", seq=5, stamp_ns=124, frame_index=1, tracker=tracker)
    assert f2.blobs[0].local_id == b.local_id


def test_playback_paces_on_the_epoch(tmp_path: Path) -> None:
    p = tmp_path / "det.txt"
    p.write_text("".join(f"{k},1,10,20,30,60,0.9\n" for k in (1, 2, 4)))
    now = [10_000_000_000]
    src = DetectionFrames(p, 2.0, lambda: now[0], epoch_ns=10_000_000_000)
    stop = threading.Event()
    f1 = src.read(stop)
    assert f1 is not None and f1.index == 0 and f1.stamp_ns == 10_000_000_000 and len(f1.payload) == 1
    now[0] = 10_500_000_000
    f2 = src.read(stop)
    assert f2 is not None and f2.index == 1 and f2.stamp_ns == 10_500_000_000
    now[0] = 11_000_000_000
    f3 = src.read(stop)
    assert f3 is not None and f3.index == 2 and f3.payload == []  # frame 3 has no boxes: an empty frame
    now[0] = 12_000_000_000  # frame 4 (1.5 s) was due 0.5 s ago: within max_lag_s, still served
    f4 = src.read(stop)
    assert f4 is not None and f4.index == 3 and f4.stamp_ns == 11_500_000_000 and f4.skipped == 0
    assert src.read(stop) is None and src.state == "ended"
    # A node that starts 3 s late (max_lag_s = 1) skips the frames it missed, counting them.
    late = DetectionFrames(p, 2.0, lambda: 13_000_000_000, epoch_ns=10_000_000_000, loop=True)
    f = late.read(stop)
    assert f is not None and f.stamp_ns == 13_000_000_000 and f.index == 6 % 4


def test_frames_read_at_once_are_the_frames_read_one_by_one() -> None:
    """Dataset time runs a file's lens model once over every box; each frame's Features are what the live node makes
    of it alone (the same blobs, the same 2D track ids, empty frames included)."""
    from common.frames import Frame
    from common.pinhole import PinholeCamera
    from sensor_node.build import DetectionProcessor

    k = np.array([[700.0, 0.0, 330.0], [0.0, 700.0, 250.0], [0.0, 0.0, 1.0]])
    cam = PinholeCamera(k, np.array([-0.3, 0.12, 0.001, -0.002, -0.02]), np.eye(3), np.array([0.0, 0.0, 3.0]), 640, 480)
    rng = np.random.default_rng(4)
    frames = []
    for i in range(12):
        dets = [
            Detection(i + 1, -1, float(u), float(v), 30.0, 80.0, 0.9)
            for u, v in zip(rng.uniform(0, 600, i % 4), rng.uniform(0, 400, i % 4), strict=True)
        ]
        frames.append(Frame(index=i, stamp_ns=1000 * i, payload=dets))
    one_by_one = DetectionProcessor("c1", cam)
    expected = [one_by_one.process_frame(f, seq=7 + i)[0] for i, f in enumerate(frames)]
    got = DetectionProcessor("c1", cam).process_frames(frames, first_seq=7)
    assert [f.seq for f in got] == [f.seq for f in expected] and [len(f.blobs) for f in got] == [0, 1, 2, 3] * 3
    for a, b in zip(got, expected, strict=True):
        for x, y in zip(a.blobs, b.blobs, strict=True):
            assert x.local_id == y.local_id
            for name in ("bearing_rad", "width_rad", "top_elev_rad", "bottom_elev_rad"):
                assert getattr(x, name) == pytest.approx(getattr(y, name), abs=1e-12)
