"""Frame sources of real cameras: OpenCV capture (device, file, RTSP/HTTP), image folder; see also
:mod:`sensor_node.detections` (MOTChallenge detection files) and, for simulated cameras, the node's
source registry (:mod:`sensor_node.build`).

Each is a :class:`common.frames.FrameSource`: it paces itself for files and folders and stamps
frames at capture. Failures do not raise out of ``read``: the source reconnects with exponential
backoff and says so in ``state`` and ``message``, which the node publishes in its status.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from common.errors import SourceError
from common.frames import Clock, Frame, Pacer
from common.schema import SourceState

__all__ = ["FolderFrames", "OpenCvFrames"]

logger = logging.getLogger(__name__)


def _backoff_wait(stop: threading.Event, seconds: float) -> bool:
    """Wait ``seconds`` unless stopped; True if stopped."""
    return stop.wait(seconds)


class OpenCvFrames:
    """``cv2.VideoCapture`` of a device index, a file or a stream, reopened with backoff on failure.

    Args:
        uri: "0" (device index), a file path, or an rtsp:// / http:// URL.
        clock: the node's clock (capture stamps).
        fps: pace file playback at this rate (0: the file's own rate).
        loop: files start again at the end.
        reconnect_min_s: first wait before reopening; doubles up to ``reconnect_max_s``.
    """

    def __init__(
        self,
        uri: str,
        clock: Clock,
        *,
        fps: float = 0.0,
        loop: bool = False,
        reconnect_min_s: float = 0.5,
        reconnect_max_s: float = 10.0,
        opener: Callable[[Any], Any] = cv2.VideoCapture,
    ) -> None:
        self.uri = uri
        self.clock = clock
        self.fps = fps
        self.loop = loop
        self.reconnect_min_s = reconnect_min_s
        self.reconnect_max_s = reconnect_max_s
        self._opener = opener
        self._target: Any = int(uri) if uri.strip().isdigit() else uri
        self.is_file = isinstance(self._target, str) and Path(self._target).is_file()
        self._cap: Any = None
        self._backoff_s = reconnect_min_s
        self._index = 0
        self._next_due = 0.0
        self.state: SourceState = "starting"
        self.message = ""
        self.reconnects = 0

    def _open(self) -> bool:
        cap = self._opener(self._target)
        if cap is None or not cap.isOpened():
            if cap is not None:
                cap.release()
            return False
        self._cap = cap
        if self.is_file:
            rate = self.fps or float(cap.get(cv2.CAP_PROP_FPS) or 0.0)
            self._period_s = 1.0 / rate if rate > 0 and math.isfinite(rate) else 0.0
            self._next_due = time.monotonic()
            if self._period_s:
                logger.info(
                    "source %s: played at %g fps (%s)", self.uri, rate, "[source] fps" if self.fps else "the file's"
                )
            else:
                logger.info("source %s: the file gives no frame rate: played as fast as it is read", self.uri)
        return True

    def _fail(self, why: str, stop: threading.Event) -> bool:
        """Record a failure and wait the backoff; True if stopped meanwhile."""
        if self._cap is not None:
            self._cap.release()
            self._cap = None
        self.state = "reconnecting"
        self.message = f"{why}; retrying in {self._backoff_s:.1f} s"
        logger.warning("source %s: %s", self.uri, self.message)
        self.reconnects += 1
        wait = self._backoff_s
        self._backoff_s = min(self.reconnect_max_s, self._backoff_s * 2)
        return _backoff_wait(stop, wait)

    def _pace(self, stop: threading.Event) -> bool:
        """Wait for a file's next frame time (devices and streams pace themselves); True if stopped meanwhile."""
        if not (self.is_file and self._period_s > 0):
            return False
        delay = self._next_due - time.monotonic()
        if delay > 0 and stop.wait(delay):
            return True
        self._next_due = max(self._next_due + self._period_s, time.monotonic() - self._period_s)
        return False

    def _read_failed(self, stop: threading.Event) -> bool:
        """After a read that gave no frame: a file ends (or starts again), a device or stream reconnects.
        True if the node is stopping meanwhile."""
        if not self.is_file:
            return self._fail(f"read from {self.uri!r} failed", stop)
        self._cap.release()
        self._cap = None
        if not self.loop:
            self.state, self.message = "ended", f"end of file {self.uri!r}"
        return False

    def read(self, stop: threading.Event) -> Frame | None:
        while not stop.is_set() and self.state != "ended":
            if self._cap is None and not self._open():
                if self._fail(f"cannot open {self.uri!r}", stop):
                    break
                continue
            if self._pace(stop):
                break
            ok, image = self._cap.read()
            stamp = self.clock()
            if ok and image is not None:
                self.state, self.message = "ok", ""
                self._backoff_s = self.reconnect_min_s
                frame = Frame(index=self._index, stamp_ns=stamp, image=image)
                self._index += 1
                return frame
            if self._read_failed(stop):
                break
        return None

    def close(self) -> None:
        if self._cap is not None:
            self._cap.release()
            self._cap = None


class FolderFrames:
    """Images of a folder in name order, paced at ``fps``.

    Raises:
        SourceError: if the folder does not exist or holds no matching image.
    """

    def __init__(self, path: Path, pattern: str, fps: float, clock: Clock, loop: bool = False) -> None:
        if not path.is_dir():
            raise SourceError(f"image folder {str(path)!r} does not exist")
        self.files = sorted(p for p in path.glob(pattern) if p.is_file())
        if not self.files:
            raise SourceError(f"image folder {str(path)!r} has no files matching {pattern!r}")
        self.loop = loop
        self.clock = clock
        self._pacer = Pacer(fps, clock, clock())
        self._pos = 0
        self._index = 0
        self.state: SourceState = "starting"
        self.message = ""

    def read(self, stop: threading.Event) -> Frame | None:
        while not stop.is_set():
            if self._pos >= len(self.files):
                if not self.loop:
                    self.state, self.message = "ended", f"all {len(self.files)} images read"
                    return None
                self._pos = 0
            slot = self._pacer.wait(stop)
            if slot is None:
                return None
            path = self.files[self._pos]
            self._pos += 1
            image = cv2.imread(str(path), cv2.IMREAD_COLOR)
            if image is None:
                self.message = f"cannot read image {path.name!r}"
                logger.warning("%s", self.message)
                continue
            self.state = "ok"
            frame = Frame(index=self._index, stamp_ns=self.clock(), image=np.ascontiguousarray(image))
            self._index += 1
            return frame
        return None

    def close(self) -> None:
        """Nothing is held open between reads."""
