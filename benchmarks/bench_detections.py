"""The sensor node's detection on real pixels, against OpenCV's own baselines, scored in the image.

Usage::

    python -m benchmarks.bench_detections [--video V.avi] [--ground-truth B.txt] [--calibration C.json]
                                          [--fps 7] [--skip-s 2] [--detectors node mog2 hog]

Default: the first 400 frames of PETS 2009 S2L1 View_001 in ``../shared`` (7 fps), first 2 s not scored.
Each detector's boxes are scored by :func:`user_agent.evaluate2d.score_detections` at IoU 0.5 and 0.3:

* **node** -- the sensor node's pipeline with default ``[pipeline]`` settings, offline
  (:func:`panostereo.commands.evaluate_detections.detect_video`, as ``panostereo evaluate-detections``);
* **mog2** -- ``cv2.createBackgroundSubtractorMOG2()`` (defaults, shadows marked and dropped), 3x3 opening and
  5x5 closing (ellipses), connected components of at least ``MIN_AREA_PX``;
* **hog** -- ``cv2.HOGDescriptor`` with the default people detector on frames scaled x2 (winStride 8, padding 8,
  scale 1.05), each window trimmed by ``HOG_PAD`` (the person inside it). OpenCV 5 has no HOG in its main
  modules: reported as unavailable there (run this benchmark with an OpenCV 4.x python for it).

Baselines' bearings are the azimuth of their box's bottom centre (they find no head). Prints one JSON object.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path
from typing import Any

os.environ.setdefault("OMP_NUM_THREADS", "1")

import cv2
import numpy as np

from user_agent.evaluate2d import Box, Detection2D, read_boxes, score_detections

REPO = Path(__file__).resolve().parent.parent
PETS = REPO.parent / "shared" / "datasets" / "pets2009_s2l1"

MIN_AREA_PX = 150
"""Least component area of the MOG2 baseline (the figure ABOUT.md quotes its reference run with)."""


HOG_PAD = (0.15, 0.05)
"""Fractions of a HOG window's width and height trimmed off each side (OpenCV's samples/python/peopledetect.py)."""


def _frames(video: Path) -> list[Any]:
    cap = cv2.VideoCapture(str(video))
    out = []
    while True:
        ok, f = cap.read()
        if not ok:
            break
        out.append(f)
    cap.release()
    return out


def _mog2(frames: list[Any]) -> dict[int, list[Detection2D]]:
    mog = cv2.createBackgroundSubtractorMOG2()
    k3 = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (3, 3))
    k5 = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (5, 5))
    out = {}
    for k, f in enumerate(frames):
        m = cv2.threshold(mog.apply(f), 200, 255, cv2.THRESH_BINARY)[1]  # shadows (127) dropped
        m = cv2.morphologyEx(cv2.morphologyEx(m, cv2.MORPH_OPEN, k3), cv2.MORPH_CLOSE, k5)
        n, _, st, _ = cv2.connectedComponentsWithStats(m)
        out[k + 1] = [Detection2D(Box(*(float(x) for x in st[i, :4]))) for i in range(1, n) if st[i, 4] >= MIN_AREA_PX]
    return out


def _hog(frames: list[Any]) -> dict[int, list[Detection2D]] | None:
    if not hasattr(cv2, "HOGDescriptor"):
        return None
    hog = cv2.HOGDescriptor()
    hog.setSVMDetector(cv2.HOGDescriptor_getDefaultPeopleDetector())
    out = {}
    for k, f in enumerate(frames):
        rects, _ = hog.detectMultiScale(cv2.resize(f, None, fx=2, fy=2), winStride=(8, 8), padding=(8, 8), scale=1.05)
        # The detection window pads the person: trimmed as OpenCV's peopledetect sample draws it.
        out[k + 1] = [
            Detection2D(Box((x + HOG_PAD[0] * w) / 2, (y + HOG_PAD[1] * h) / 2, w * (1 - 2 * HOG_PAD[0]) / 2,
                            h * (1 - 2 * HOG_PAD[1]) / 2))
            for (x, y, w, h) in rects
        ]  # fmt: skip
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--video", default=str(PETS / "video" / "view001_0000-0399.avi"))
    p.add_argument("--ground-truth", default=str(PETS / "video" / "view001_gt_boxes.txt"))
    p.add_argument("--calibration", default=str(PETS / "calib" / "view001.json"))
    p.add_argument("--fps", type=float, default=7.0, help="true frame rate (PETS: ~7; its container says 10)")
    p.add_argument("--skip-s", type=float, default=2.0)
    p.add_argument("--detectors", nargs="+", default=["node", "mog2", "hog"], choices=["node", "mog2", "hog"])
    args = p.parse_args(argv)
    cv2.setNumThreads(1)
    truth = read_boxes(Path(args.ground_truth))
    from common.pinhole import PinholeCamera

    cam = PinholeCamera.from_calibration(json.loads(Path(args.calibration).read_text()), args.calibration)

    def bearing_of(u: float, v: float) -> float:
        return float(cam.bearing_elevation(np.array([[u, v]], np.float64))[0][0])

    frames = _frames(Path(args.video))
    scored = [k for k in range(1, len(frames) + 1) if (k - 1) / args.fps >= args.skip_s - 1e-9]
    result: dict[str, Any] = {
        "benchmark": "sensor_node.detections_2d",
        "video": args.video,
        "frames": len(frames),
        "fps": args.fps,
        "scored_frames": len(scored),
        "opencv": cv2.__version__,
    }
    for name in args.detectors:
        t0 = time.perf_counter()
        startup: float | None = 0.0
        if name == "node":
            from panostereo.commands.evaluate_detections import _node_config, detect_video

            ns = argparse.Namespace(config=None, calibration=args.calibration, fps=args.fps)
            run = detect_video(_node_config(ns, Path(args.video)), fps=args.fps)
            found: dict[int, list[Detection2D]] | None = run.found
            startup = (run.first_reported - 1) / args.fps if run.first_reported else None
        elif name == "mog2":
            found = _mog2(frames)
        else:
            found = _hog(frames)
        if found is None:
            result[name] = {"available": False, "why": f"cv2 {cv2.__version__} has no HOGDescriptor"}
            continue
        scores = score_detections(truth, found, scored, bearing_of=bearing_of)
        result[name] = {
            "startup_s": None if startup is None else round(startup, 3),
            **{f"iou_{s.iou:g}": s.summary() for s in scores},
            "wall_s": round(time.perf_counter() - t0, 1),
        }
    json.dump(result, sys.stdout, indent=2)
    sys.stdout.write("\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
