"""Convert a Wildtrack-format dataset (Wildtrack, MultiviewX) into a runnable site.

Input layout (annotations and calibration only; no images needed)::

    annotations_positions/NNNNNNNN.json   one per annotated frame (N = video frame, every 5th at 10 fps)
    calibrations/intrinsic_zero/intr_<CAM>.xml   OpenCV FileStorage: camera_matrix (undistorted images;
                                                 MultiviewX: calibrations/intrinsic/)
    calibrations/extrinsic/extr_<CAM>.xml        rvec, tvec (world -> camera), tvec in centimetres

Each annotation lists ``{personID, positionID, views: [{viewNum, xmin, ymin,
xmax, ymax}]}`` (a box of -1 = not visible); the floor position is
``X = x0 + step * (positionID % width)``, ``Y = y0 + step * (positionID // width)``.
``viewNum`` i is the i-th camera in name order (CVLab1..4, IDIAP1..3).

Output (``--out DIR``)::

    site.toml                 [site] + [dataset] + one [[process]] per camera and the manager
    calib/<cam>.json          {"model": "pinhole", "image_size", "K", "dist" (zero), "R" (Rodrigues), "t" (metres)}
    detections/<cam>.txt      MOTChallenge det file from the annotated boxes: frame,-1,left,top,w,h,conf,-1,-1,-1
                              (no identities: ground truth never reaches the pipeline), optional pixel noise
                              and dropped boxes
    nodes/<cam>.toml          sensor-node config (detections source), nodes/manager.toml
    gt.csv                    frame,id,x_m,y_m (frames 1-based at 2 fps)
"""

from __future__ import annotations

import json
import logging
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from common.errors import ConfigError
from user_agent.groundtruth import GtPoint, write_gt_rows

__all__ = ["GridSpec", "ImportResult", "import_wildtrack"]

logger = logging.getLogger(__name__)

_ID_CLEAN = re.compile(r"[^a-z0-9-]+")


@dataclass(frozen=True, slots=True)
class GridSpec:
    """The ground-plane grid of ``positionID`` and the calibration's length unit."""

    x0_m: float = -3.0
    y0_m: float = -9.0
    step_m: float = 0.025
    width: int = 480
    extrinsic_unit_m: float = 0.01
    """Metres per unit of ``tvec`` (Wildtrack: centimetres)."""
    video_fps: float = 10.0
    frame_step: int = 5
    """Annotated every ``frame_step``-th video frame: the site runs at video_fps / frame_step."""


@dataclass(frozen=True, slots=True)
class ImportResult:
    site: Path
    cameras: list[str]
    frames: int
    people: int
    boxes: int
    dropped: int


def _read_fs(path: Path, node: str) -> np.ndarray:
    if not path.is_file():
        raise ConfigError(f"{path}: calibration file not found")
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    try:
        n = fs.getNode(node)
        if n.empty():
            raise ConfigError(f"{path}: no {node!r} entry")
        if n.isSeq():
            return np.array([n.at(i).real() for i in range(n.size())], dtype=np.float64)
        m = n.mat()
        if m is None:
            raise ConfigError(f"{path}: {node!r} is not a matrix")
        return np.asarray(m, dtype=np.float64)
    finally:
        fs.release()


def _cameras(root: Path) -> list[str]:
    ext = root / "calibrations" / "extrinsic"
    names = sorted(p.stem.removeprefix("extr_") for p in ext.glob("extr_*.xml"))
    if not names:
        raise ConfigError(f"{root}: expected calibrations/extrinsic/extr_<CAM>.xml files, found none")
    return names


def camera_id(name: str) -> str:
    """``CVLab1`` -> ``cvlab1`` (a valid sensor id)."""
    cid = _ID_CLEAN.sub("-", name.lower()).strip("-")
    if not cid:
        raise ConfigError(f"camera name {name!r} gives an empty sensor id")
    return cid


def calibration(root: Path, name: str, grid: GridSpec, image_size: tuple[int, int]) -> dict[str, Any]:
    """The pinhole calibration JSON of one camera (metres)."""
    intr = root / "calibrations" / "intrinsic_zero" / f"intr_{name}.xml"
    if not intr.is_file():  # MultiviewX: synthetic, undistorted images with one intrinsic folder
        intr = root / "calibrations" / "intrinsic" / f"intr_{name}.xml"
    k = _read_fs(intr, "camera_matrix").reshape(3, 3)
    extr = root / "calibrations" / "extrinsic" / f"extr_{name}.xml"
    rvec = _read_fs(extr, "rvec").reshape(3)
    tvec = _read_fs(extr, "tvec").reshape(3)
    rot, _ = cv2.Rodrigues(rvec)
    return {
        "model": "pinhole",
        "image_size": [int(image_size[0]), int(image_size[1])],
        "K": k.tolist(),
        "dist": [0.0, 0.0, 0.0, 0.0, 0.0],
        "R": np.asarray(rot).tolist(),
        "t": (tvec * grid.extrinsic_unit_m).tolist(),
    }


def _annotations(root: Path) -> list[tuple[int, list[dict[str, Any]]]]:
    folder = root / "annotations_positions"
    files = sorted(folder.glob("*.json"))
    if not files:
        raise ConfigError(f"{root}: expected annotations_positions/*.json, found none")
    out = []
    for f in files:
        try:
            out.append((int(f.stem), json.loads(f.read_text(encoding="utf-8"))))
        except (ValueError, json.JSONDecodeError) as err:
            raise ConfigError(f"{f}: not a Wildtrack annotation file: {err}") from err
    return out


def _site_toml(cams: list[str], fps: float, frames: int) -> str:
    lines = [
        "# A dataset site made by `panostereo import wildtrack`: detection files + gt.csv, no simulation.",
        "# Run: panostereo demo --site THIS_FILE",
        "",
        "[site]",
        'name = "wildtrack"',
        'prefix = "pano"',
        f"fps = {fps}",
        f"duration_s = {frames / fps:.1f}",
        "seed = 1",
        'router = "tcp/127.0.0.1:7447"',
        "",
        "[dataset]",
        'ground_truth = "gt.csv"',
        f"fps = {fps}",
        f"frames = {frames}",
    ]
    for cid in cams:
        lines += ["", "[[process]]", f'name = "{cid}"', 'command = "node"', f'config = "nodes/{cid}.toml"']
    lines += ["", "[[process]]", 'name = "manager"', 'command = "manager"', 'config = "nodes/manager.toml"']
    return "\n".join(lines) + "\n"


def _node_toml(cid: str, fps: float) -> str:
    return f"""# Detection-file camera {cid} (made by `panostereo import wildtrack`).

[node]
id = "{cid}"
prefix = "pano"
bearing_sigma_rad = 0.0035

[zenoh]
mode = "client"
connect = ["tcp/127.0.0.1:7447"]

[source]
kind = "detections"
file = "../detections/{cid}.txt"
calibration = "../calib/{cid}.json"
fps = {fps}
max_lag_s = 1.0
"""


def _manager_toml(fps: float) -> str:
    period_ms = 1000.0 / fps
    return f"""# Resource manager of the imported dataset site: frames come every {period_ms:.0f} ms.

[manager]
id = "mgr1"
prefix = "pano"
rate_hz = {max(2.0, 2 * fps):g}
latency_ms = {period_ms + 300:.0f}            # a frame period plus delivery
max_gap_ms = {2.5 * period_ms:.0f}           # interpolate between consecutive annotated frames
stale_ms = {3 * period_ms:.0f}
max_extrapolation_ms = {0.6 * period_ms:.0f}
state_dir = ""

[zenoh]
mode = "client"
connect = ["tcp/127.0.0.1:7447"]

[match]
use_colour = false              # detection files carry no colour
max_range_m = 50.0
threshold = 0.1                 # without colour (r_is = 1) Eq. 7's product is larger-spread: accept lower

[tracker]
max_misses = 3                  # ticks: a person unseen for ~0.75 s at 2 fps has left (longer makes ghosts coast)

[mutual]
enabled = false                 # static, calibrated cameras

[planner]
enabled = false
"""


def import_wildtrack(
    root: str | Path,
    out: str | Path,
    *,
    noise_px: float = 0.0,
    drop_rate: float = 0.0,
    seed: int = 0,
    grid: GridSpec | None = None,
    image_size: tuple[int, int] = (1920, 1080),
    max_frames: int = 0,
) -> ImportResult:
    """Convert the dataset at ``root`` into a site under ``out``.

    Args:
        noise_px: std-dev of Gaussian noise added to each box edge (pixels).
        drop_rate: probability that an annotated box is left out (a missed detection).
        seed: random seed of the noise and drops.
        max_frames: keep only the first N annotated frames (0: all).

    Raises:
        ConfigError: missing or malformed input, bad arguments.
    """
    src, dst = Path(root), Path(out)
    g = grid or GridSpec()
    if not src.is_dir():
        raise ConfigError(f"{src}: no such dataset folder")
    if noise_px < 0 or not math.isfinite(noise_px):
        raise ConfigError(f"--noise-px must be >= 0, got {noise_px}")
    if not 0.0 <= drop_rate < 1.0:
        raise ConfigError(f"--drop-rate must be in [0, 1), got {drop_rate}")
    if src.resolve() == dst.resolve() or dst.resolve().is_relative_to(src.resolve()):
        raise ConfigError(f"--out {dst} must not be inside the dataset folder {src}")
    names = _cameras(src)
    ids = [camera_id(n) for n in names]
    if len(set(ids)) != len(ids):
        raise ConfigError(f"{src}: camera names {names} give duplicate sensor ids {ids}")
    fps = g.video_fps / g.frame_step
    anns = _annotations(src)
    if max_frames > 0:
        anns = anns[:max_frames]
    rng = np.random.default_rng(seed)
    w, h = image_size
    dets: dict[int, list[str]] = {i: [] for i in range(len(names))}
    gt: list[GtPoint] = []
    boxes = dropped = 0
    for video_frame, people in anns:
        if video_frame % g.frame_step:
            raise ConfigError(f"{src}: annotation {video_frame:08d}.json is not a multiple of {g.frame_step}")
        frame = video_frame // g.frame_step + 1
        for person in people:
            pos = int(person["positionID"])
            x = g.x0_m + g.step_m * (pos % g.width)
            y = g.y0_m + g.step_m * (pos // g.width)
            gt.append(GtPoint(frame, str(int(person["personID"])), round(x, 4), round(y, 4)))
            for view in person.get("views", []):
                v = int(view["viewNum"])
                box = [float(view[k]) for k in ("xmin", "ymin", "xmax", "ymax")]
                if v not in dets or box == [-1.0, -1.0, -1.0, -1.0]:
                    continue
                boxes += 1
                if drop_rate and rng.random() < drop_rate:
                    dropped += 1
                    continue
                if noise_px:
                    box = [b + float(rng.normal(0.0, noise_px)) for b in box]
                x0, y0 = min(max(box[0], 0.0), w - 1.0), min(max(box[1], 0.0), h - 1.0)
                x1, y1 = min(max(box[2], 0.0), w - 1.0), min(max(box[3], 0.0), h - 1.0)
                if x1 - x0 < 2 or y1 - y0 < 2:
                    dropped += 1
                    continue
                dets[v].append(f"{frame},-1,{x0:.1f},{y0:.1f},{x1 - x0:.1f},{y1 - y0:.1f},1.0,-1,-1,-1")
    frames = max(p.frame for p in gt) if gt else 0
    for sub in ("calib", "detections", "nodes"):
        (dst / sub).mkdir(parents=True, exist_ok=True)
    for i, (name, cid) in enumerate(zip(names, ids, strict=True)):
        calib = calibration(src, name, g, image_size)
        (dst / "calib" / f"{cid}.json").write_text(json.dumps(calib, indent=1) + "\n", encoding="utf-8")
        (dst / "detections" / f"{cid}.txt").write_text("\n".join(dets[i]) + "\n", encoding="utf-8")
        (dst / "nodes" / f"{cid}.toml").write_text(_node_toml(cid, fps), encoding="utf-8")
    (dst / "nodes" / "manager.toml").write_text(_manager_toml(fps), encoding="utf-8")
    write_gt_rows(dst / "gt.csv", gt, with_z=False)
    site = dst / "site.toml"
    site.write_text(_site_toml(ids, fps, frames), encoding="utf-8")
    logger.info("imported %d cameras, %d frames, %d boxes (%d dropped) into %s", len(ids), frames, boxes, dropped, dst)
    return ImportResult(site, ids, frames, len({p.person_id for p in gt}), boxes, dropped)
