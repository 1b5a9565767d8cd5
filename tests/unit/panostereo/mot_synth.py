"""A small calibrated multi-view detection dataset made in the test: pinhole cameras around a floor, people
walking, each camera's boxes projected from them (feet to head top), in the ``import mot`` layout."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from common.pinhole import PinholeCamera

SIZE = (1280, 720)
K = [[900.0, 0.0, 640.0], [0.0, 900.0, 360.0], [0.0, 0.0, 1.0]]
CAMERAS = {"north": (5.0, 14.0, 3.0), "east": (14.0, 5.0, 3.0), "southwest": (-3.0, -3.0, 3.5)}
"""Camera id -> (x, y, height) of its optical centre; each looks at the floor's middle (5, 5)."""


def look_at(x: float, y: float, z: float, target: tuple[float, float] = (5.0, 5.0)) -> dict[str, object]:
    """Pinhole calibration JSON of a camera at (x, y, z) looking at ``target`` on the floor."""
    c = np.array([x, y, z])
    fwd = np.array([target[0], target[1], 0.0]) - c
    fwd /= np.linalg.norm(fwd)
    right = np.cross(fwd, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    down = np.cross(fwd, right)
    r = np.array([right, down, fwd])  # world -> camera rows: x right, y down, z forward
    t = -r @ c
    return {"model": "pinhole", "image_size": list(SIZE), "K": K, "dist": [0.0] * 5, "R": r.tolist(), "t": t.tolist()}


def person_at(pid: int, frame: int, fps: float) -> tuple[float, float]:
    """Person ``pid``'s floor position at 1-based ``frame``: two walk across the floor, one stands still."""
    t = (frame - 1) / fps
    if pid == 0:
        return 1.0 + 0.6 * t, 3.0
    if pid == 1:
        return 8.0 - 0.5 * t, 6.5
    return 4.0, 8.0


def write_dataset(root: Path, *, frames: int = 30, fps: float = 5.0, people: int = 3, clutter: bool = False) -> None:
    """``calib/``, ``detections/`` and ``gt.csv`` under ``root``; ``clutter`` adds one false box per frame in one
    camera where nobody is."""
    (root / "calib").mkdir(parents=True, exist_ok=True)
    (root / "detections").mkdir(parents=True, exist_ok=True)
    gt = ["frame,id,x_m,y_m"]
    lines: dict[str, list[str]] = {cid: [] for cid in CAMERAS}
    cams = {}
    for cid, (x, y, z) in CAMERAS.items():
        calib = look_at(x, y, z)
        (root / "calib" / f"{cid}.json").write_text(json.dumps(calib))
        cams[cid] = PinholeCamera.from_calibration(calib, cid)
    for k in range(1, frames + 1):
        for pid in range(people):
            px, py = person_at(pid, k, fps)
            gt.append(f"{k},{pid + 1},{px:.3f},{py:.3f}")
            for cid, cam in cams.items():
                c = cam.center_world
                d = math.hypot(px - c[0], py - c[1])
                side = np.array([-(py - c[1]), px - c[0]]) / d * 0.22
                pts = np.array([[px + side[0], py + side[1], 0.0], [px - side[0], py - side[1], 0.0], [px, py, 1.75]])
                uv, front = cam.project(pts)
                if not front.all():
                    continue
                left, right = float(min(uv[:2, 0])), float(max(uv[:2, 0]))
                top, bottom = float(uv[2, 1]), float(max(uv[:2, 1]))
                if right < 0 or left > SIZE[0] or bottom < 0 or top > SIZE[1]:
                    continue
                left, right = max(left, 0.0), min(right, SIZE[0] - 1.0)
                top, bottom = max(top, 0.0), min(bottom, SIZE[1] - 1.0)
                lines[cid].append(f"{k},-1,{left:.1f},{top:.1f},{right - left:.1f},{bottom - top:.1f},0.9,-1,-1,-1")
        if clutter:
            lines["north"].append(f"{k},-1,100.0,300.0,30.0,80.0,0.8,-1,-1,-1")
    for cid, rows in lines.items():
        (root / "detections" / f"{cid}.txt").write_text("\n".join(rows) + "\n")
    (root / "gt.csv").write_text("\n".join(gt) + "\n")
