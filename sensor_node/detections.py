"""Detection files: a camera whose person detector runs elsewhere.

Input: a MOTChallenge detection file -- one box per line,
``frame,id,left,top,width,height,conf[,x,y,z]``, comma-separated, 1-based
frames at a given fps -- and the camera's pinhole calibration JSON
(:meth:`common.cameras.PinholeCamera.from_calibration`).

Output: the same :class:`~common.schema.Features` an image node publishes, so
the manager runs unchanged on a real detector's output. For a box:

* bearing -- world azimuth of the ray through the box's *bottom centre* (the
  feet: on the floor, directly below the head);
* width -- angle between the rays through the bottom corners;
* top / bottom elevation -- elevations of the rays through the top and bottom
  centres (above the horizontal plane through the optical centre);
* no colour (``hist = []``); the confidence is the ``conf`` column;
* local id -- the file's ``id`` column when it is >= 0, else a 2D tracker's.

The node's pose is the camera centre with yaw 0: bearings are world azimuths.
"""

from __future__ import annotations

import json
import math
import threading
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from common.angles import wrap_angle
from common.arrays import FloatArray
from common.cameras import PinholeCamera
from common.errors import ConfigError, SourceError
from common.frames import Clock, Frame, Pacer
from common.numbers import clip
from common.schema import Blob, Features, Pose, SourceState
from sensor_node.config import read_start_file
from sensor_node.tracks2d import Tracker2D

__all__ = ["Detection", "DetectionFrames", "features_from_detections", "load_calibration", "read_mot"]

MOT_FIELDS = 7
"""A MOTChallenge line has at least frame, id, left, top, width, height, conf."""


@dataclass(frozen=True, slots=True)
class Detection:
    """One box of a MOTChallenge detection file."""

    frame: int
    """1-based frame number."""
    track_id: int
    """The file's id column (-1: none)."""
    left_px: float
    top_px: float
    width_px: float
    height_px: float
    conf: float


def read_mot(path: Path, min_confidence: float = 0.0) -> dict[int, list[Detection]]:
    """Parse a MOTChallenge det file into {frame: [detections]}.

    Raises:
        SourceError: missing file, or a line that is not ``frame,id,left,top,width,height,conf,...``,
            naming the file, the line number, what was expected and what was found.
    """
    try:
        text = path.read_text()
    except OSError as err:
        raise SourceError(f"cannot read detection file {str(path)!r}: {err.strerror}") from err
    out: dict[int, list[Detection]] = {}
    for n, line in enumerate(text.splitlines(), start=1):
        s = line.strip()
        if not s or s.startswith("#"):
            continue
        parts = [p.strip() for p in s.split(",")]
        try:
            if len(parts) < MOT_FIELDS:
                raise ValueError(f"{len(parts)} fields")
            frame = int(float(parts[0]))
            vals = [float(p) for p in parts[1:7]]
        except ValueError as err:
            raise SourceError(
                f"{path}:{n}: expected 'frame,id,left,top,width,height,conf,...' (numbers), got {s!r}"
            ) from err
        tid, left, top, w, h, conf = vals
        if frame < 1 or w <= 0 or h <= 0 or not all(math.isfinite(v) for v in vals):
            raise SourceError(f"{path}:{n}: expected frame >= 1 and a positive finite box, got {s!r}")
        if conf < min_confidence:
            continue
        out.setdefault(frame, []).append(Detection(frame, int(tid), left, top, w, h, conf))
    return out


def load_calibration(path: Path) -> PinholeCamera:
    """Read a pinhole calibration JSON.

    Raises:
        ConfigError: unreadable or invalid JSON, or a calibration :class:`PinholeCamera` refuses.
    """
    try:
        data = json.loads(path.read_text())
    except OSError as err:
        raise ConfigError(f"cannot read calibration {str(path)!r}: {err.strerror}") from err
    except json.JSONDecodeError as err:
        raise ConfigError(f"{path}: invalid JSON: {err}") from err
    if not isinstance(data, dict) or data.get("model") != "pinhole":
        got = data.get("model") if isinstance(data, dict) else type(data).__name__
        raise ConfigError(f"{path}: model: expected 'pinhole', got {got!r}")
    return PinholeCamera.from_calibration(data, str(path))


def camera_pose(camera: PinholeCamera) -> Pose:
    """Pose of a calibrated pinhole camera: its centre, yaw 0 (bearings are world azimuths)."""
    c = camera.center_world
    return Pose(x_m=float(c[0]), y_m=float(c[1]), z_m=float(c[2]), yaw_rad=0.0)


def box_pixels(dets: list[Detection]) -> FloatArray:
    """(5 n, 2) the pixels each box is read at, five per box: bottom centre (the bearing), bottom left and right
    (the width), top centre (the top elevation), middle."""
    uv = np.empty((5 * len(dets), 2), dtype=np.float64)
    for i, d in enumerate(dets):
        cx, bottom = d.left_px + d.width_px / 2.0, d.top_px + d.height_px
        uv[5 * i : 5 * i + 5] = [
            (cx, bottom),
            (d.left_px, bottom),
            (d.left_px + d.width_px, bottom),
            (cx, d.top_px),
            (cx, d.top_px + d.height_px / 2.0),
        ]
    return uv


def features_from_detections(
    dets: list[Detection],
    camera: PinholeCamera,
    *,
    sensor_id: str,
    seq: int,
    stamp_ns: int,
    frame_index: int,
    tracker: Tracker2D | None = None,
    rays: tuple[FloatArray, FloatArray] | None = None,
) -> Features:
    """Turn one frame's boxes into Features (world azimuths; see the module docstring).

    ``rays``: the azimuths and elevations of :func:`box_pixels` of ``dets``, when already computed (many frames
    at once: :meth:`~sensor_node.build.DetectionProcessor.process_frames`).
    """
    if not dets:
        if tracker is not None:
            tracker.update([])
        return Features(sensor_id=sensor_id, seq=seq, stamp_ns=stamp_ns, frame_index=frame_index)
    n = len(dets)
    az, el = camera.bearing_elevation(box_pixels(dets)) if rays is None else rays
    az = az.reshape(n, 5)
    el = el.reshape(n, 5)
    ids = [d.track_id for d in dets]
    if tracker is not None and any(i < 0 for i in ids):
        tracked = tracker.update([(float(az[i, 0]), float(el[i, 3])) for i in range(n)])
        ids = [d.track_id if d.track_id >= 0 else 1_000_000 + t for d, t in zip(dets, tracked, strict=True)]
    blobs = []
    half = math.pi / 2
    for i, d in enumerate(dets):
        dw = float(az[i, 1] - az[i, 2])
        width = abs(wrap_angle(dw))
        inside = (
            d.left_px > 0 and d.left_px + d.width_px < camera.width_px and d.top_px + d.height_px < camera.height_px
        )
        blobs.append(
            Blob(
                local_id=max(0, ids[i]),
                bearing_rad=wrap_angle(float(az[i, 0])),
                width_rad=width,
                top_elev_rad=clip(float(el[i, 3]), -half, half),
                bottom_elev_rad=clip(float(el[i, 0]), -half, half),
                bbox_u_px=float(d.left_px),
                bbox_v_px=float(d.top_px),
                bbox_w_px=float(d.width_px),
                bbox_h_px=float(d.height_px),
                hist=[],
                changed_frac=1.0,
                feet_visible=bool(inside),
                confidence=clip(d.conf, 0.0, 1.0),
            )
        )
    return Features(sensor_id=sensor_id, seq=seq, stamp_ns=stamp_ns, frame_index=frame_index, blobs=blobs[:256])


class DetectionFrames:
    """Plays a detection file in real time: file frame k at ``epoch + (k - 1) / fps``.

    Frames due more than ``max_lag_s`` ago when the node gets to them (it started late) are skipped and counted;
    frames without boxes still yield an (empty) frame so the manager knows the camera saw nobody. With a
    ``start_file`` instead of an epoch, playing waits (state "starting") until the launcher writes the epoch
    there, once every process of the site is up: frame 1 is then played whatever the start-up took.
    """

    def __init__(
        self,
        path: Path,
        fps: float,
        clock: Clock,
        *,
        epoch_ns: int,
        min_confidence: float = 0.0,
        max_lag_s: float = 1.0,
        loop: bool = False,
        start_file: Path | None = None,
    ) -> None:
        self.path = path
        self.by_frame = read_mot(path, min_confidence)
        self.last_frame = max(self.by_frame, default=0)
        if self.last_frame == 0:
            raise SourceError(f"detection file {str(path)!r} holds no detections")
        self.fps = fps
        self.clock = clock
        self.epoch_ns = epoch_ns
        self.max_lag_ns = int(max_lag_s * 1e9)
        self.loop = loop
        self.start_file = start_file
        self._pacer: Pacer | None = None if start_file is not None else Pacer(fps, clock, epoch_ns, self.max_lag_ns)
        self.state: SourceState = "starting"
        self.message = "waiting for the site to start" if start_file is not None else ""

    def _started(self, stop: threading.Event) -> Pacer | None:
        """The pacer, once the epoch is known (waits for the start file; None if stopped first)."""
        while self._pacer is None:
            assert self.start_file is not None
            epoch = read_start_file(self.start_file)
            if epoch is not None:
                self.epoch_ns = epoch
                self._pacer = Pacer(self.fps, self.clock, epoch, self.max_lag_ns)
            elif stop.wait(START_POLL_S):
                return None
        return self._pacer

    def read(self, stop: threading.Event) -> Frame | None:
        pacer = self._started(stop)
        if pacer is None:
            return None
        skipped = 0
        while not stop.is_set():
            slot = pacer.wait(stop)
            if slot is None:
                return None
            k, stamp, missed = slot
            skipped += missed
            frame = k + 1
            if self.loop:
                frame = (k % self.last_frame) + 1
            elif frame > self.last_frame:
                self.state, self.message = "ended", f"end of {self.path.name} (frame {self.last_frame})"
                return None
            self.state, self.message = "ok", ""
            return Frame(index=frame - 1, stamp_ns=stamp, payload=self.by_frame.get(frame, []), skipped=skipped)
        return None

    def close(self) -> None:
        """Nothing is held open."""


START_POLL_S = 0.05
"""How often a source waiting for the site's start looks at the start file."""
