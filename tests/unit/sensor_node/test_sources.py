"""Frame sources: pacing, OpenCV reconnect with backoff (state and message), image folders, simulated goals."""

from __future__ import annotations

import threading
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

from common.errors import SourceError
from sensor_node.sources import FolderFrames, OpenCvFrames
from tests.support import skip_or_fail


class FakeClock:
    def __init__(self, t_ns: int = 1_000_000_000) -> None:
        self.t_ns = t_ns

    def __call__(self) -> int:
        return self.t_ns


class FakeCapture:
    """A cv2.VideoCapture stand-in: opens after ``fail_opens`` tries, then yields ``frames`` frames and fails."""

    def __init__(self, script: dict[str, Any]) -> None:
        self.script = script
        script["opens"] += 1
        self.ok = script["opens"] > script["fail_opens"]
        self.left = script["frames"]

    def isOpened(self) -> bool:
        return self.ok

    def read(self) -> tuple[bool, Any]:
        if self.left <= 0:
            return False, None
        self.left -= 1
        return True, np.zeros((4, 4, 3), np.uint8)

    def get(self, prop: int) -> float:
        return 0.0

    def release(self) -> None:
        self.script["released"] += 1


def test_opencv_source_reconnects_with_backoff_and_reports_it() -> None:
    script = {"opens": 0, "fail_opens": 2, "frames": 2, "released": 0}
    clock = FakeClock()
    src = OpenCvFrames(
        "rtsp://camera.invalid/stream",
        clock,
        reconnect_min_s=0.01,
        reconnect_max_s=0.02,
        opener=lambda target: FakeCapture(script),
    )
    states: list[tuple[str, str]] = []
    stop = threading.Event()
    frames = []
    while len(frames) < 4:
        f = src.read(stop)
        assert f is not None
        frames.append(f)
        states.append((src.state, src.message))
    assert [f.index for f in frames] == [0, 1, 2, 3]
    assert all(s == ("ok", "") for s in states)
    assert src.reconnects >= 3  # two failed opens, then a failed read -> reopen
    assert script["opens"] >= 4
    # While the stream is down the state says so, with the reason.
    script["fail_opens"] = 10**9
    script["frames"] = 0
    t = threading.Thread(target=src.read, args=(stop,), daemon=True)
    t.start()
    deadline = 2.0
    t0 = time.monotonic()
    while src.state != "reconnecting" and time.monotonic() - t0 < deadline:
        time.sleep(0.005)
    assert src.state == "reconnecting" and "camera.invalid" in src.message and "retrying" in src.message
    stop.set()
    t.join(2.0)
    assert not t.is_alive()
    src.close()


def test_opencv_file_source_ends_or_loops(tmp_path: Path) -> None:
    path = tmp_path / "clip.avi"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 50.0, (64, 48))
    if not writer.isOpened():
        skip_or_fail("no MJPG video writer in this OpenCV build")
    for k in range(5):
        writer.write(np.full((48, 64, 3), 40 * k, np.uint8))
    writer.release()
    src = OpenCvFrames(str(path), FakeClock(), fps=200.0)
    stop = threading.Event()
    got = []
    while (f := src.read(stop)) is not None:
        got.append(f)
    assert len(got) == 5 and src.state == "ended"
    looping = OpenCvFrames(str(path), FakeClock(), fps=200.0, loop=True)
    assert len([looping.read(stop) for _ in range(12)]) == 12 and looping.state == "ok"


def test_folder_source(tmp_path: Path) -> None:
    for k in range(3):
        cv2.imwrite(str(tmp_path / f"f{k:03d}.png"), np.full((8, 8, 3), 50 * k, np.uint8))
    (tmp_path / "notes.txt").write_text("not an image")
    clock = FakeClock()
    src = FolderFrames(tmp_path, "*.png", 1000.0, clock)
    stop = threading.Event()
    got = [src.read(stop) for _ in range(3)]
    assert [int(f.image[0, 0, 0]) for f in got if f is not None and f.image is not None] == [0, 50, 100]
    assert src.read(stop) is None and src.state == "ended"
    with pytest.raises(SourceError, match="no files matching"):
        FolderFrames(tmp_path, "*.jpg", 10.0, clock)
    with pytest.raises(SourceError, match="does not exist"):
        FolderFrames(tmp_path / "missing", "*.png", 10.0, clock)
