"""Turn any calibrated multi-view detection dataset into a runnable site (``panostereo import mot``).

Input layout (``DIR``)::

    calib/<cam>.json        {"model": "pinhole", "image_size": [w, h], "K", "dist", "R", "t"} (world -> camera,
                            metres; the JSON the detection source reads, ``sensor_node.detections``)
    detections/<cam>.txt    MOTChallenge det file: frame,id,left,top,width,height,conf[,...], 1-based frames
    gt.csv                  optional ground truth: frame,id,x_m,y_m[,z_m] (same frame numbers)

Every camera with both a calibration and a detection file becomes a sensor node; frame ``k`` of every file is
the same instant, world time ``(k - 1) / fps``. The frame rate is the dataset's fact, so it is given
(``--fps``); so is the area (``--area X0,Y0,X1,Y1``, the floor people can be in), when known: it is written to
the site's ``[area]``, where the tracker starts people and scores every track.

Output (``--out SITE_DIR``)::

    site.toml               [site] + [dataset] + one [[process]] per camera and the manager
    calib/<cam>.json        copied
    detections/<cam>.txt    copied, or with pixel noise / dropped boxes (``noise_px``, ``drop_rate``)
    gt.csv                  copied (when given)
    nodes/<cam>.toml        a detection-source node per camera; nodes/manager.toml

The configs hold only the site's facts (ids, frame rate, area, where the files are) and no tuning: the
manager runs its defaults, as on every other site. ``panostereo demo --site SITE_DIR/site.toml`` runs the
site through the network; ``panostereo evaluate-site SITE_DIR/site.toml`` plays it in dataset time.
"""

from __future__ import annotations

import json
import logging
import math
import re
import shutil
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from common.area import Area, AreaSpec
from common.errors import ConfigError
from common.keys import validate_id
from common.pinhole import PinholeCamera
from user_agent.groundtruth import read_gt_csv

__all__ = ["ImportResult", "camera_id", "import_mot", "write_site"]

logger = logging.getLogger(__name__)

_ID_CLEAN = re.compile(r"[^a-z0-9-]+")
MIN_BOX_PX = 2.0
"""Boxes narrower or lower than this after noise and clipping are dropped (no person is two pixels tall)."""


@dataclass(frozen=True, slots=True)
class ImportResult:
    site: Path
    cameras: list[str]
    frames: int
    people: int
    boxes: int
    dropped: int


def camera_id(name: str) -> str:
    """A file or camera name as a valid sensor id (``View_001`` -> ``view-001``)."""
    cid = _ID_CLEAN.sub("-", name.lower()).strip("-")
    if not cid:
        raise ConfigError(f"camera name {name!r} gives an empty sensor id")
    return cid


def _check_calibration(path: Path) -> tuple[int, int]:
    """The image size of a calibration JSON, after checking the camera model accepts it."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError) as err:
        raise ConfigError(f"{path}: not a readable calibration JSON: {err}") from err
    if not isinstance(data, dict) or data.get("model") != "pinhole":
        got = data.get("model") if isinstance(data, dict) else type(data).__name__
        raise ConfigError(f"{path}: model: expected 'pinhole', got {got!r}")
    cam = PinholeCamera.from_calibration(data, str(path))
    return cam.width_px, cam.height_px


def _perturb(
    src: Path, dst: Path, size: tuple[int, int], *, noise_px: float, drop_rate: float, rng: np.random.Generator
) -> tuple[int, int, int]:
    """Copy a det file with Gaussian noise on every box edge and boxes dropped at random.

    Returns:
        (boxes read, boxes dropped, last frame).
    """
    w, h = size
    out: list[str] = []
    boxes = dropped = last = 0
    for n, line in enumerate(src.read_text(encoding="utf-8").splitlines(), start=1):
        s = line.strip()
        if not s or s.startswith("#"):
            continue
        parts = [p.strip() for p in s.split(",")]
        try:
            frame = int(float(parts[0]))
            left, top, bw, bh = (float(p) for p in parts[2:6])
        except (ValueError, IndexError) as err:
            raise ConfigError(f"{src}:{n}: expected 'frame,id,left,top,width,height,conf,...', got {s!r}") from err
        boxes += 1
        last = max(last, frame)
        if drop_rate and rng.random() < drop_rate:
            dropped += 1
            continue
        x0, y0, x1, y1 = left, top, left + bw, top + bh
        if noise_px:
            x0, y0, x1, y1 = (v + float(rng.normal(0.0, noise_px)) for v in (x0, y0, x1, y1))
        x0, x1 = min(max(x0, 0.0), w - 1.0), min(max(x1, 0.0), w - 1.0)
        y0, y1 = min(max(y0, 0.0), h - 1.0), min(max(y1, 0.0), h - 1.0)
        if x1 - x0 < MIN_BOX_PX or y1 - y0 < MIN_BOX_PX:
            dropped += 1
            continue
        rest = parts[6:] or ["1.0"]
        box = [f"{x0:.2f}", f"{y0:.2f}", f"{x1 - x0:.2f}", f"{y1 - y0:.2f}"]
        out.append(",".join([str(frame), parts[1], *box, *rest]))
    dst.write_text("\n".join(out) + "\n", encoding="utf-8")
    return boxes, dropped, last


def _last_frame(path: Path) -> tuple[int, int]:
    """(boxes, last frame) of a det file (only the frame column is read)."""
    boxes = last = 0
    for line in path.read_text(encoding="utf-8").splitlines():
        s = line.strip()
        if not s or s.startswith("#"):
            continue
        try:
            last = max(last, int(float(s.split(",", 1)[0])))
        except ValueError as err:
            raise ConfigError(f"{path}: expected a frame number first on every line, got {s!r}") from err
        boxes += 1
    return boxes, last


def _area_toml(area: AreaSpec) -> list[str]:
    corners = ", ".join(f"[{x:g}, {y:g}]" for x, y in area.polygon)
    lines = ["", "[area]  # the floor where people can be (a fact of the site, metres)", f"polygon = [{corners}]"]
    if area.exits is not None:
        exits = ", ".join("[" + ", ".join(f"[{x:g}, {y:g}]" for x, y in ex) + "]" for ex in area.exits)
        lines.append(f"exits = [{exits}]")
    return lines


def _site_toml(name: str, cams: Sequence[str], fps: float, frames: int, *, has_gt: bool, area: AreaSpec | None) -> str:
    lines = [
        f"# A dataset site made by `panostereo import`: {len(cams)} calibrated cameras' detection files"
        + (" and their ground truth." if has_gt else "."),
        "# Run it through the network: panostereo demo --site THIS_FILE",
        "# Play it in dataset time and score it: panostereo evaluate-site THIS_FILE",
        "",
        "[site]",
        f'name = "{name}"',
        'prefix = "pano"',
        f"fps = {fps:g}",
        f"duration_s = {max(frames / fps, 1.0):.1f}",
        "seed = 1",
        'router = "tcp/127.0.0.1:7447"',
        "",
        "[dataset]",
        f"fps = {fps:g}",
        f"frames = {frames}",
    ]
    if has_gt:
        lines.append('ground_truth = "gt.csv"')
    if area is not None:
        lines += _area_toml(area)
    for cid in cams:
        lines += ["", "[[process]]", f'name = "{cid}"', 'command = "node"', f'config = "nodes/{cid}.toml"']
    lines += ["", "[[process]]", 'name = "manager"', 'command = "manager"', 'config = "nodes/manager.toml"']
    return "\n".join(lines) + "\n"


def _node_toml(cid: str, fps: float, min_confidence: float, shared_detector: str) -> str:
    shared = f'shared_detector = "{shared_detector}"\n' if shared_detector else ""
    return f"""# Detection-file camera {cid} (made by `panostereo import`): its boxes and its calibration.

[node]
id = "{cid}"
prefix = "pano"

[zenoh]
mode = "client"
connect = ["tcp/127.0.0.1:7447"]

[source]
kind = "detections"
file = "../detections/{cid}.txt"
calibration = "../calib/{cid}.json"
fps = {fps:g}
min_confidence = {min_confidence:g}
{shared}"""


MANAGER_TOML = """# Resource manager of the imported dataset site: the defaults, as on every site.

[manager]
id = "mgr1"
prefix = "pano"
state_dir = ""

[zenoh]
mode = "client"
connect = ["tcp/127.0.0.1:7447"]
"""


def write_site(
    out: Path,
    *,
    name: str,
    cameras: Sequence[str],
    fps: float,
    frames: int,
    has_gt: bool,
    area: AreaSpec | None = None,
    min_confidence: float = 0.0,
    shared_detector: str = "",
) -> Path:
    """Write ``site.toml`` and the per-process configs for files already under ``out/calib``, ``out/detections``."""
    (out / "nodes").mkdir(parents=True, exist_ok=True)
    for cid in cameras:
        node = _node_toml(cid, fps, min_confidence, shared_detector)
        (out / "nodes" / f"{cid}.toml").write_text(node, encoding="utf-8")
    (out / "nodes" / "manager.toml").write_text(MANAGER_TOML, encoding="utf-8")
    site = out / "site.toml"
    site.write_text(_site_toml(name, cameras, fps, frames, has_gt=has_gt, area=area), encoding="utf-8")
    return site


def _check_args(fps: float, area: AreaSpec | None, noise_px: float, drop_rate: float, min_conf: float) -> None:
    if not (math.isfinite(fps) and fps > 0):
        raise ConfigError(f"--fps must be > 0 (the dataset's frame rate), got {fps}")
    if area is not None:
        Area.of(area, "--area")
    if noise_px < 0 or not math.isfinite(noise_px):
        raise ConfigError(f"--noise-px must be >= 0, got {noise_px}")
    if not 0.0 <= drop_rate < 1.0:
        raise ConfigError(f"--drop-rate must be in [0, 1), got {drop_rate}")
    if not 0.0 <= min_conf <= 1.0:
        raise ConfigError(f"--min-confidence must be in [0, 1], got {min_conf}")


@dataclass(frozen=True, slots=True)
class _CameraFiles:
    """One camera of the dataset: its sensor id and its two files."""

    sensor_id: str
    calib: Path
    detections: Path


def _camera_files(src: Path) -> list[_CameraFiles]:
    """The cameras with both a calibration and a detection file, by name; a camera with only one is left out.

    Raises:
        ConfigError: no camera has both, or two camera names give the same sensor id.
    """
    calib_dir, det_dir = src / "calib", src / "detections"
    calibs = {p.stem: p for p in sorted(calib_dir.glob("*.json"))}
    dets = {p.stem: p for p in sorted(det_dir.glob("*.txt"))}
    names = sorted(set(calibs) & set(dets))
    if not names:
        raise ConfigError(
            f"{src}: expected calib/<cam>.json and detections/<cam>.txt for the same cameras, "
            f"found calibrations {sorted(calibs)} and detection files {sorted(dets)}"
        )
    for orphan in sorted(set(calibs) ^ set(dets)):
        has = "a calibration" if orphan in calibs else "detections"
        logger.warning("%s: camera %r has %s only: left out", src, orphan, has)
    ids = [camera_id(n) for n in names]
    if len(set(ids)) != len(ids):
        raise ConfigError(f"{src}: camera names {names} give duplicate sensor ids {ids}")
    return [_CameraFiles(cid, calibs[n], dets[n]) for n, cid in zip(names, ids, strict=True)]


def _import_camera(
    cam: _CameraFiles, dst: Path, *, noise_px: float, drop_rate: float, rng: np.random.Generator
) -> tuple[int, int, int]:
    """Copy one camera's calibration and detections into ``dst`` (perturbed when asked).

    Returns:
        (boxes written, boxes dropped, last frame).
    """
    size = _check_calibration(cam.calib)
    shutil.copyfile(cam.calib, dst / "calib" / f"{cam.sensor_id}.json")
    if noise_px or drop_rate:
        return _perturb(
            cam.detections,
            dst / "detections" / f"{cam.sensor_id}.txt",
            size,
            noise_px=noise_px,
            drop_rate=drop_rate,
            rng=rng,
        )
    shutil.copyfile(cam.detections, dst / "detections" / f"{cam.sensor_id}.txt")
    b, last = _last_frame(cam.detections)
    return b, 0, last


def import_mot(
    root: str | Path,
    out: str | Path,
    *,
    fps: float,
    area: AreaSpec | None = None,
    min_confidence: float = 0.0,
    noise_px: float = 0.0,
    drop_rate: float = 0.0,
    seed: int = 0,
    name: str = "",
    shared_detector: str = "",
) -> ImportResult:
    """Convert the dataset at ``root`` (layout in the module docstring) into a site under ``out``.

    Args:
        fps: the dataset's frame rate (frame k is world time (k - 1) / fps).
        area: the floor people can be in (and its exits), if known: the site's ``[area]``.
        min_confidence: the nodes ignore boxes whose ``conf`` column is lower (the detector's operating point).
        noise_px: std-dev of Gaussian noise added to each box edge (pixels): a robustness study.
        drop_rate: probability that a box is left out (a missed detection): a robustness study.
        seed: random seed of the noise and drops.
        name: the site's name (default: the folder's).
        shared_detector: the name of the multi-view detector whose floor detections the boxes are, drawn into every
            view (an annotation made on the floor, a multi-view detector's output); "": each camera's boxes are its
            own detector's (:attr:`~sensor_node.config.DetectionsSource.shared_detector`).

    Raises:
        ConfigError: missing or malformed input, bad arguments.
    """
    src, dst = Path(root), Path(out)
    if not src.is_dir():
        raise ConfigError(f"{src}: no such dataset folder")
    _check_args(fps, area, noise_px, drop_rate, min_confidence)
    if shared_detector:
        validate_id(shared_detector, "--shared-detector")
    if src.resolve() == dst.resolve() or dst.resolve().is_relative_to(src.resolve()):
        raise ConfigError(f"--out {dst} must not be inside the dataset folder {src}")
    cameras = _camera_files(src)
    ids = [cam.sensor_id for cam in cameras]
    gt_src = src / "gt.csv"
    gt = read_gt_csv(gt_src) if gt_src.is_file() else None
    for sub in ("calib", "detections"):
        (dst / sub).mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    boxes = dropped = frames = 0
    for cam in cameras:
        b, d, last = _import_camera(cam, dst, noise_px=noise_px, drop_rate=drop_rate, rng=rng)
        boxes, dropped, frames = boxes + b, dropped + d, max(frames, last)
    people = 0
    if gt is not None:
        shutil.copyfile(gt_src, dst / "gt.csv")
        frames = max(frames, max(gt.frame_numbers, default=0))
        people = len(gt.person_ids)
    site = write_site(
        dst,
        name=camera_id(name or src.resolve().name),
        cameras=ids,
        fps=fps,
        frames=frames,
        has_gt=gt is not None,
        area=area,
        min_confidence=min_confidence,
        shared_detector=shared_detector,
    )
    logger.info("imported %d cameras, %d frames, %d boxes (%d dropped) into %s", len(ids), frames, boxes, dropped, dst)
    return ImportResult(site, ids, frames, people, boxes, dropped)
