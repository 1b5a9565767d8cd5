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

This is a front end to the generic importer (:mod:`panostereo.datasets.mot`): it writes the dataset in that
importer's layout and lets it build the site::

    calib/<cam>.json          {"model": "pinhole", "image_size", "K", "dist" (zero), "R" (Rodrigues), "t" (metres)}
    detections/<cam>.txt      MOTChallenge det file from the annotated boxes: frame,-1,left,top,w,h,conf,-1,-1,-1
                              (no identities: ground truth never reaches the pipeline)
    gt.csv                    frame,id,x_m,y_m (frames 1-based at 2 fps)

then ``site.toml`` and ``nodes/*.toml`` as every imported site has them, with the importer's optional pixel noise
and dropped boxes.
"""

from __future__ import annotations

import json
import logging
import math
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from common.area import rectangle
from common.errors import ConfigError
from panostereo.datasets.mot import MIN_BOX_PX, ImportResult, camera_id, import_mot
from user_agent.groundtruth import GtPoint, write_gt_rows

__all__ = ["GridSpec", "ImportResult", "import_wildtrack"]

WILDTRACK_ANNOTATION = "wildtrack-annotation"
"""The imported cameras' shared detector: Wildtrack's boxes are its annotated floor positions, each drawn into every
view as one fixed box (:attr:`~sensor_node.config.DetectionsSource.shared_detector`): the annotator boxes people
behind anyone, and a gap in the annotation is every view's at once."""

logger = logging.getLogger(__name__)


@dataclass(frozen=True, slots=True)
class GridSpec:
    """The ground-plane grid of ``positionID`` and the calibration's length unit."""

    x0_m: float = -3.0
    y0_m: float = -9.0
    step_m: float = 0.025
    width: int = 480
    rows: int = 1440
    """Cells per column: the grid spans ``width`` x ``rows`` cells, the annotated area."""
    extrinsic_unit_m: float = 0.01
    """Metres per unit of ``tvec`` (Wildtrack: centimetres)."""
    video_fps: float = 10.0
    frame_step: int = 5
    """Annotated every ``frame_step``-th video frame: the site runs at video_fps / frame_step."""


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


def _check_import(src: Path, dst: Path, noise_px: float, drop_rate: float) -> None:
    """Raises ConfigError for a missing dataset, bad noise or drop rate, or an output inside the dataset."""
    if not src.is_dir():
        raise ConfigError(f"{src}: no such dataset folder")
    if noise_px < 0 or not math.isfinite(noise_px):
        raise ConfigError(f"--noise-px must be >= 0, got {noise_px}")
    if not 0.0 <= drop_rate < 1.0:
        raise ConfigError(f"--drop-rate must be in [0, 1), got {drop_rate}")
    if src.resolve() == dst.resolve() or dst.resolve().is_relative_to(src.resolve()):
        raise ConfigError(f"--out {dst} must not be inside the dataset folder {src}")


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
    site_name: str = "",
) -> ImportResult:
    """Convert the dataset at ``root`` into a site under ``out``.

    Args:
        noise_px: std-dev of Gaussian noise added to each box edge (pixels).
        drop_rate: probability that an annotated box is left out (a missed detection).
        seed: random seed of the noise and drops.
        max_frames: keep only the first N annotated frames (0: all).
        site_name: the site's name (default ``wildtrack``).

    Raises:
        ConfigError: missing or malformed input, bad arguments.
    """
    src, dst = Path(root), Path(out)
    g = grid or GridSpec()
    _check_import(src, dst, noise_px, drop_rate)
    names = _cameras(src)
    ids = [camera_id(n) for n in names]
    if len(set(ids)) != len(ids):
        raise ConfigError(f"{src}: camera names {names} give duplicate sensor ids {ids}")
    fps = g.video_fps / g.frame_step
    anns = _annotations(src)
    if max_frames > 0:
        anns = anns[:max_frames]
    w, h = image_size
    dets: dict[int, list[str]] = {i: [] for i in range(len(names))}
    gt: list[GtPoint] = []
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
                x0, y0 = min(max(box[0], 0.0), w - 1.0), min(max(box[1], 0.0), h - 1.0)
                x1, y1 = min(max(box[2], 0.0), w - 1.0), min(max(box[3], 0.0), h - 1.0)
                if x1 - x0 < MIN_BOX_PX or y1 - y0 < MIN_BOX_PX:
                    continue  # a box outside the image (clipped to nothing)
                dets[v].append(f"{frame},-1,{x0:.1f},{y0:.1f},{x1 - x0:.1f},{y1 - y0:.1f},1.0,-1,-1,-1")
    with tempfile.TemporaryDirectory(prefix="wildtrack-") as tmp:
        stage = Path(tmp)
        for sub in ("calib", "detections"):
            (stage / sub).mkdir()
        for i, (name, cid) in enumerate(zip(names, ids, strict=True)):
            calib = calibration(src, name, g, image_size)
            (stage / "calib" / f"{cid}.json").write_text(json.dumps(calib, indent=1) + "\n", encoding="utf-8")
            (stage / "detections" / f"{cid}.txt").write_text("\n".join(dets[i]) + "\n", encoding="utf-8")
        write_gt_rows(stage / "gt.csv", gt, with_z=False)
        # The annotated ground grid is where the dataset says people are: the site's area.
        area = rectangle(g.x0_m, g.y0_m, g.x0_m + g.step_m * g.width, g.y0_m + g.step_m * g.rows)
        return import_mot(
            stage,
            dst,
            fps=fps,
            area=area,
            noise_px=noise_px,
            drop_rate=drop_rate,
            seed=seed,
            name=site_name or "wildtrack",
            shared_detector=WILDTRACK_ANNOTATION,
        )
