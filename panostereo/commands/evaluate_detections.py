"""``panostereo evaluate-detections``: score one camera's blobs in the image against ground-truth boxes.

Usage::

    panostereo evaluate-detections VIDEO_OR_RECORDING --ground-truth BOXES.txt [--calibration C.json]
                                   [--config NODE.toml] [--fps F] [--skip-s 2] [--sensor ID] [--json]

A video is played offline, frame by frame, through the sensor node's own
pipeline (:func:`sensor_node.build.build_node` with the node config given, or
a pinhole camera from ``--calibration`` with default ``[pipeline]`` settings):
no clock, no zenoh, the same figures on every run. Frame k (0-based) is
stamped k / fps. A recording (``.mcap``, from ``agent record`` or a demo run)
is scored as the live node published it: its Features by ``frame_index``, its
SensorInfo's pinhole model for bearings.

Ground truth is a MOTChallenge box file (``frame,id,left,top,width,height,...``,
frame 1 = the video's first frame); it is read only here. The figures (see
:mod:`user_agent.evaluate2d`): recall, precision, MODA, merges, people with no
blob, blobs too wide, bottom offset and bearing error, at IoU 0.5 and 0.3, over
the frames from ``--skip-s`` on; and the start-up: when the first frame was
reported on.
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import msgspec
import numpy as np

from common.cli import non_negative, positive
from common.errors import ConfigError, SourceError
from user_agent.evaluate2d import Box, Detection2D, read_boxes, score_detections

__all__ = ["DetectionRun", "configure", "detect_video", "run"]

logger = logging.getLogger(__name__)


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the command's flags."""
    parser.add_argument("source", help="video file (played through the pipeline) or .mcap recording")
    parser.add_argument("--ground-truth", required=True, metavar="BOXES", help="MOTChallenge box file, 1-based frames")
    parser.add_argument("--calibration", default=None, metavar="JSON", help="pinhole calibration (bearings)")
    parser.add_argument("--config", default=None, metavar="TOML", help="sensor-node config ([camera], [pipeline])")
    parser.add_argument(
        "--fps", type=positive, default=None, help="video frame rate (default: the config's, else the file's)"
    )
    parser.add_argument(
        "--skip-s", type=non_negative, default=2.0, help="seconds from the first frame not scored (default 2)"
    )
    parser.add_argument("--ignore-above-row", type=float, default=0.0, help="unmatched blobs ending above are no FP")
    parser.add_argument("--sensor", default=None, help="recording: the sensor to score (default: the only one)")
    parser.add_argument("--max-frames", type=int, default=0, help="video: stop after this many frames (0: all)")
    parser.add_argument("--json", action="store_true", help="print JSON only")


@dataclass(slots=True)
class DetectionRun:
    """What a detector reported on a video or recording."""

    found: dict[int, list[Detection2D]]
    """Blobs by 1-based frame."""
    stamps_s: dict[int, float]
    """Each reported frame's time since the first frame."""
    first_reported: int | None
    """1-based frame of the first frame reported on (the background model ready), None: never."""
    camera: Any = None
    """PinholeCamera for bearings, if known."""
    processing_ms: float = 0.0
    """Mean pipeline time per frame (videos)."""
    fps: float = 0.0
    """The frame rate the video was played at (0: a recording, played at its own stamps)."""
    fps_from: str = ""
    """Where that rate came from: ``--fps``, the node config, or the file."""


def _node_config(args: argparse.Namespace, video: Path) -> Any:
    """The node config to run the video through: ``--config`` (its source replaced), else a pinhole camera."""
    from sensor_node.config import load_node_config

    if args.config:
        cfg = load_node_config(args.config)
        data = msgspec.to_builtins(cfg)
        data["source"] = {"kind": "opencv", "uri": str(video), "fps": args.fps or getattr(cfg.source, "fps", 0.0)}
        if args.calibration and data.get("camera", {}).get("model") == "pinhole":
            data["camera"]["calibration"] = str(Path(args.calibration).resolve())
        from sensor_node.config import NodeConfig

        return _validated(data, NodeConfig, args.config)
    if not args.calibration:
        raise ConfigError("a video needs --calibration (pinhole JSON) or --config (node config)")
    from sensor_node.config import NodeConfig

    data = {
        "node": {"id": "evaluate"},
        "source": {"kind": "opencv", "uri": str(video), "fps": args.fps or 0.0},
        "camera": {"model": "pinhole", "calibration": str(Path(args.calibration).resolve())},
    }
    return _validated(data, NodeConfig, "--calibration")


def _validated(data: dict[str, Any], kind: type, where: str) -> Any:
    """The node config the command built, validated; a value it refuses is named, never a traceback."""
    from sensor_node.config import validate

    try:
        return validate(msgspec.convert(data, kind))
    except msgspec.ValidationError as err:
        raise ConfigError(f"{where}: {err}") from err


def detect_video(cfg: Any, *, fps: float | None = None, max_frames: int = 0) -> DetectionRun:
    """Play a video (the config's ``[source] uri``) through the node's pipeline offline; frame k at k / fps.

    Raises:
        SourceError: the file cannot be opened or holds no frame.
    """
    import cv2

    from common.frames import Frame
    from sensor_node.build import build_node

    path = Path(cfg.source.uri)
    cap = cv2.VideoCapture(str(path))
    if not cap.isOpened():
        raise SourceError(f"cannot open video {str(path)!r}")
    file_fps = float(cap.get(cv2.CAP_PROP_FPS) or 0.0)
    rate, source = next(
        ((r, name) for r, name in ((fps, "--fps"), (cfg.source.fps, "the node config"), (file_fps, "the file")) if r),
        (0.0, ""),
    )
    if not (rate > 0 and math.isfinite(rate)):
        cap.release()
        raise SourceError(f"{path}: the file gives no frame rate: pass --fps")
    parts = build_node(cfg, lambda: 0)
    parts.source.close()
    run = DetectionRun({}, {}, None, getattr(getattr(parts.processor, "pipeline", None), "geometry", None))
    run.fps, run.fps_from = rate, source
    run.camera = getattr(run.camera, "camera", None)
    k = 0
    spent = 0.0
    try:
        while not max_frames or k < max_frames:
            ok, image = cap.read()
            if not ok or image is None:
                break
            stamp = round(k / rate * 1e9)
            t0 = time.perf_counter()
            features, state = parts.processor.process_frame(Frame(index=k, stamp_ns=stamp, image=image), k)
            spent += time.perf_counter() - t0
            if state in ("ok", "relit") and run.first_reported is None:
                run.first_reported = k + 1
            run.found[k + 1] = [_detection(b) for b in features.blobs]
            run.stamps_s[k + 1] = k / rate
            k += 1
    finally:
        cap.release()
    if k == 0:
        raise SourceError(f"{path}: no frame could be read")
    run.processing_ms = spent / k * 1e3
    return run


def _detection(b: Any) -> Detection2D:
    # Blob boxes are whole pixels (centres at integers): the box's edges are half a pixel out.
    return Detection2D(Box(b.bbox_u_px - 0.5, b.bbox_v_px - 0.5, b.bbox_w_px, b.bbox_h_px), float(b.bearing_rad))


def detect_recording(path: Path, sensor: str | None) -> DetectionRun:
    """A recording's Features of one sensor, by frame.

    Raises:
        ConfigError: no Features in it, or several sensors and none chosen.
    """
    from common.cameras import PinholeCamera
    from common.keys import DEFAULT_PREFIX, Keys
    from common.schema import Features, PinholeModel, SensorInfo
    from user_agent.messages import decode_on_key
    from user_agent.recording import iter_raw, read_metadata

    keys = Keys(read_metadata(path).get("prefix", DEFAULT_PREFIX))
    feats: dict[str, list[Features]] = {}
    infos: dict[str, SensorInfo] = {}
    for raw in iter_raw(path):
        msg = decode_on_key(keys, raw.key, raw.data)
        if isinstance(msg, Features):
            feats.setdefault(msg.sensor_id, []).append(msg)
        elif isinstance(msg, SensorInfo):
            infos[msg.sensor_id] = msg
    if not feats:
        raise ConfigError(f"{path}: no sensor Features in the recording")
    if sensor is None:
        if len(feats) > 1:
            raise ConfigError(f"{path}: several sensors ({', '.join(sorted(feats))}): choose one with --sensor")
        sensor = next(iter(feats))
    if sensor not in feats:
        raise ConfigError(f"{path}: --sensor {sensor!r} has no Features (sensors: {', '.join(sorted(feats))})")
    run = DetectionRun({}, {}, None)
    msgs = sorted(feats[sensor], key=lambda f: f.frame_index)
    t0 = msgs[0].stamp_ns
    for f in msgs:
        k = f.frame_index + 1
        if f.state == "ok" and run.first_reported is None:
            run.first_reported = k
        run.found[k] = [_detection(b) for b in f.blobs]
        run.stamps_s[k] = (f.stamp_ns - t0) / 1e9
    info = infos.get(sensor)
    if info is not None and isinstance(info.model, PinholeModel):
        run.camera = PinholeCamera.from_model(info.model)
    return run


def run(args: argparse.Namespace) -> int:
    """Score and print; returns 0."""
    source = Path(args.source)
    if not source.is_file():
        raise ConfigError(f"{source}: no such file")
    if args.max_frames < 0:
        raise ConfigError(f"--max-frames must be >= 0 (0: all), got {args.max_frames}")
    truth = read_boxes(Path(args.ground_truth))
    if source.suffix.lower() == ".mcap":
        det = detect_recording(source, args.sensor)
    else:
        det = detect_video(_node_config(args, source), fps=args.fps, max_frames=args.max_frames)
    if args.calibration:
        from sensor_node.detections import load_calibration

        det.camera = load_calibration(Path(args.calibration))
    camera = det.camera

    def bearing_of(u: float, v: float) -> float:
        az, _ = camera.bearing_elevation(np.array([[u, v]], np.float64))
        return float(az[0])

    frames = [k for k, t in sorted(det.stamps_s.items()) if t >= args.skip_s - 1e-9]
    scores = score_detections(
        truth, det.found, frames, bearing_of=bearing_of if camera is not None else None,
        ignore_above_row=args.ignore_above_row,
    )  # fmt: skip
    first = det.first_reported
    result: dict[str, Any] = {
        "source": str(source),
        "ground_truth": str(args.ground_truth),
        "frames": len(det.found),
        "scored_frames": len(frames),
        "skip_s": args.skip_s,
        "startup_s": round(det.stamps_s[first], 3) if first is not None else None,
        "first_reported_frame": first,
        "processing_ms_per_frame": round(det.processing_ms, 3) if det.processing_ms else None,
        "fps": det.fps or None,
        "fps_from": det.fps_from or "the recording's stamps",
        **{f"iou_{s.iou:g}": s.summary() for s in scores},
    }
    if args.json:
        print(json.dumps(result, indent=2))
        return 0
    rate = f"played at {det.fps:g} fps (from {det.fps_from})" if det.fps else "at the recording's own stamps"
    print(f"{source.name}: {result['frames']} frames {rate}, scored {len(frames)} from {args.skip_s:g} s; "
          f"start-up {result['startup_s']} s")  # fmt: skip
    cols = ("recall", "precision", "moda", "merged_frac", "no_blob_frac", "too_wide_frac", "bearing_err_deg_median")
    print("IoU   " + "  ".join(f"{c:>22}" for c in cols))
    for s in scores:
        row = s.summary()
        print(f"{s.iou:<5g} " + "  ".join(f"{_fmt(row[c]):>22}" for c in cols))
    return 0


def _fmt(x: Any) -> str:
    return "-" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:g}"
