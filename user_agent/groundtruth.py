"""Ground-truth files: ``gt.csv`` with header ``frame,id,x_m,y_m[,z_m]``.

Frames are 1-based at the site's fps: frame ``k`` is world time
``(k - 1) / fps`` seconds after the run's epoch. The simulator writes this file
for its runs and ``panostereo import wildtrack`` writes it for a dataset; only
evaluation and plotting read it (ground truth never flows into the pipeline).
"""

from __future__ import annotations

import csv
import itertools
import math
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from common.arrays import FloatArray
from common.errors import ConfigError

__all__ = ["GT_HEADER", "WALKING_MPS", "GroundTruth", "GtPoint", "median_speed_mps", "read_gt_csv", "speed_warning",
           "write_gt_rows"]  # fmt: skip

MIN_HULL_POINTS = 3
"""The scored area is the convex hull of the ground truth's positions: it needs three distinct points."""


GT_HEADER = ("frame", "id", "x_m", "y_m", "z_m")
WALKING_MPS = (0.1, 3.0)
"""People's median speed over a scene lies in this range; a ground truth that implies another at the given frame
rate was most likely given the wrong one (a 7 fps set read as 70 fps walks at a tenth of its speed)."""
MIN_STEPS = 10
"""A median speed needs at least this many steps of one person between frames."""


@dataclass(frozen=True, slots=True)
class GtPoint:
    """One person's true floor position at one frame."""

    frame: int
    """1-based frame number."""
    person_id: str
    x_m: float
    y_m: float
    z_m: float = 0.0
    """Height (of the head top, or 0 when the file has no ``z_m``)."""


@dataclass(frozen=True, slots=True)
class GroundTruth:
    """A whole ``gt.csv``: points grouped by frame."""

    frames: dict[int, list[GtPoint]]
    source: str = ""

    @property
    def frame_numbers(self) -> list[int]:
        return sorted(self.frames)

    @property
    def person_ids(self) -> list[str]:
        return sorted({p.person_id for pts in self.frames.values() for p in pts})

    def area(self) -> FloatArray | None:
        """(k, 2) the convex hull of every annotated floor position, counter-clockwise: where the ground truth
        says who is there (None: fewer than three distinct points)."""
        pts = np.unique(np.array([[p.x_m, p.y_m] for pts in self.frames.values() for p in pts]).reshape(-1, 2), axis=0)
        if len(pts) < MIN_HULL_POINTS:
            return None
        try:
            hull = ConvexHull(pts)
        except QhullError:  # all points on a line
            return None
        return np.asarray(pts[hull.vertices], dtype=np.float64)

    def track_of(self, person_id: str) -> list[GtPoint]:
        """One person's points in frame order."""
        return [p for k in self.frame_numbers for p in self.frames[k] if p.person_id == person_id]


def median_speed_mps(gt: GroundTruth, fps: float) -> float | None:
    """The median speed of the people between consecutive annotated frames at ``fps`` (None: too few steps)."""
    steps: list[float] = []
    for pid in gt.person_ids:
        pts = gt.track_of(pid)
        for a, b in itertools.pairwise(pts):
            if b.frame > a.frame:
                steps.append(math.hypot(b.x_m - a.x_m, b.y_m - a.y_m) * fps / (b.frame - a.frame))
    return float(np.median(steps)) if len(steps) >= MIN_STEPS else None


def speed_warning(gt: GroundTruth, fps: float) -> str | None:
    """A warning when the ground truth implies people walk implausibly fast or slowly at ``fps``, else None."""
    speed = median_speed_mps(gt, fps)
    if speed is None or WALKING_MPS[0] <= speed <= WALKING_MPS[1]:
        return None
    lo, hi = WALKING_MPS
    return (
        f"at {fps:g} fps the ground truth ({gt.source or 'gt.csv'}) has people walking at {speed:.2f} m/s (median), "
        f"outside the {lo:g}-{hi:g} m/s people walk: is the frame rate right?"
    )


def _float(row: dict[str, str], key: str, where: str) -> float:
    raw = row.get(key)
    try:
        value = float(raw) if raw is not None else math.nan
    except ValueError as err:
        raise ConfigError(f"{where}: {key} must be a number, got {raw!r}") from err
    if not math.isfinite(value):
        raise ConfigError(f"{where}: {key} must be a finite number, got {raw!r}")
    return value


def read_gt_csv(path: str | Path) -> GroundTruth:
    """Read a ``gt.csv``.

    Raises:
        ConfigError: missing file, missing columns, or a bad value (naming the line).
    """
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError as err:
        raise ConfigError(f"{p}: no such ground-truth file") from err
    except OSError as err:
        raise ConfigError(f"{p}: cannot read ground-truth file: {err.strerror}") from err
    reader = csv.DictReader(text.splitlines())
    fields = [f.strip() for f in (reader.fieldnames or [])]
    missing = [c for c in GT_HEADER[:4] if c not in fields]
    if missing:
        raise ConfigError(f"{p}: expected a header with frame,id,x_m,y_m[,z_m], got {','.join(fields) or 'nothing'}")
    frames: dict[int, list[GtPoint]] = {}
    for lineno, raw in enumerate(reader, start=2):
        row = {k.strip(): (v or "").strip() for k, v in raw.items() if k is not None}
        where = f"{p}:{lineno}"
        try:
            frame = int(row["frame"])
        except ValueError as err:
            raise ConfigError(f"{where}: frame must be an integer, got {row['frame']!r}") from err
        if frame < 1:
            raise ConfigError(f"{where}: frame must be >= 1 (1-based), got {frame}")
        pid = row["id"]
        if not pid:
            raise ConfigError(f"{where}: id must not be empty")
        z = _float(row, "z_m", where) if row.get("z_m") else 0.0
        point = GtPoint(frame, pid, _float(row, "x_m", where), _float(row, "y_m", where), z)
        frames.setdefault(frame, []).append(point)
    return GroundTruth(frames=frames, source=str(p))


def write_gt_rows(path: str | Path, points: Iterable[GtPoint], with_z: bool = True) -> int:
    """Write points as a ``gt.csv``; returns the number of rows written."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    n = 0
    with p.open("w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(GT_HEADER if with_z else GT_HEADER[:4])
        for pt in sorted(points, key=lambda q: (q.frame, q.person_id)):
            row = [pt.frame, pt.person_id, f"{pt.x_m:.4f}", f"{pt.y_m:.4f}"]
            if with_z:
                row.append(f"{pt.z_m:.4f}")
            w.writerow(row)
            n += 1
    return n
