"""Detection accuracy in the image: one camera's blob boxes against ground-truth boxes, frame by frame.

Pure (no zenoh, no mcap, no pipeline): boxes in, figures out. Used by
``panostereo evaluate-detections`` and ``benchmarks/bench_detections.py``.

Per frame, blobs and ground-truth boxes are paired one to one by the Hungarian
algorithm on ``1 - IoU``; a pair counts as a match when its IoU reaches the
threshold (0.5 and 0.3 are reported). Then, CLEAR-MOT's detection part:

* ``recall = matches / objects``, ``precision = matches / blobs``;
* ``MODA = 1 - (misses + false positives) / objects``;
* **bearing error** of a match: the blob's bearing (its head's ray) minus the
  azimuth of the ray through the ground-truth box's bottom centre (the feet,
  directly below the head of someone upright), when a camera model gives it;
* **merged**: the ground-truth box is mostly (``COVER_FRAC``) inside a blob that
  mostly holds someone else's box too; **no blob**: no blob covers even
  ``NO_BLOB_COVER`` of the box; **too wide**: the blob that covers the box most,
  holding nobody else, is ``TOO_WIDE`` times as wide or more; the median
  bottom offset (blob bottom minus box bottom, rows) of those same blobs.

Frames before ``skip_s`` are not scored (the start-up is reported apart); a
blob whose bottom lies above ``ignore_above_row`` and that matches nobody is no
false positive (a region the annotation leaves out, e.g. people far in the
background of PETS 2009 View_001).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import numpy.typing as npt
from scipy.optimize import linear_sum_assignment

from common.angles import angle_diff
from common.errors import ConfigError

__all__ = [
    "Box",
    "Detection2D",
    "DetectionScores",
    "iou_matrix",
    "read_boxes",
    "score_detections",
]

BOX_FIELDS = 6
"""A ground-truth box line has at least frame, id, left, top, width, height."""
MERGED_PEOPLE = 2
"""A blob that holds this many people's boxes or more is a merge."""

COVER_FRAC = 0.5
"""Fraction of a ground-truth box inside a blob for the blob to hold that person (merges)."""

NO_BLOB_COVER = 0.25
"""A ground-truth box that no blob covers this much of has no blob at all."""

TOO_WIDE = 1.5
"""A lone person's blob this many times as wide as their box or more is too wide (shadow, trail)."""


@dataclass(frozen=True, slots=True)
class Box:
    """An axis-aligned image box, pixels (left, top inclusive; width, height)."""

    left_px: float
    top_px: float
    width_px: float
    height_px: float

    @property
    def bottom_px(self) -> float:
        return self.top_px + self.height_px


@dataclass(frozen=True, slots=True)
class Detection2D:
    """One blob (or a baseline detector's box) in one frame."""

    box: Box
    bearing_rad: float = math.nan
    """The blob's reported bearing (nan: none; then the box's bottom centre is used)."""


@dataclass(slots=True)
class DetectionScores:
    """The figures at one IoU threshold."""

    iou: float
    frames: int = 0
    objects: int = 0
    """Ground-truth boxes in the scored frames."""
    blobs: int = 0
    """Blobs in the scored frames (ignored ones excluded)."""
    matches: int = 0
    misses: int = 0
    false_positives: int = 0
    merged: int = 0
    no_blob: int = 0
    too_wide: int = 0
    bearing_err_deg: list[float] = field(default_factory=list)
    bottom_err_px: list[float] = field(default_factory=list)

    def summary(self) -> dict[str, float | int | None]:
        """Rates and medians, rounded, for JSON."""
        n = max(self.objects, 1)
        err = np.abs(np.asarray(self.bearing_err_deg))
        bottom = np.asarray(self.bottom_err_px)
        return {
            "iou": self.iou,
            "frames": self.frames,
            "objects": self.objects,
            "blobs": self.blobs,
            "matches": self.matches,
            "misses": self.misses,
            "false_positives": self.false_positives,
            "recall": round(self.matches / n, 4),
            "precision": round(self.matches / max(self.blobs, 1), 4),
            "moda": round(1.0 - (self.misses + self.false_positives) / n, 4),
            "merged_frac": round(self.merged / n, 4),
            "no_blob_frac": round(self.no_blob / n, 4),
            "too_wide_frac": round(self.too_wide / n, 4),
            "bearing_err_deg_median": round(float(np.median(err)), 4) if err.size else None,
            "bearing_err_deg_p90": round(float(np.percentile(err, 90)), 4) if err.size else None,
            "bottom_err_px_median": round(float(np.median(bottom)), 2) if bottom.size else None,
        }

    def as_dict(self) -> dict[str, object]:
        return asdict(self)


def read_boxes(path: Path) -> dict[int, list[Box]]:
    """A MOTChallenge box file (``frame,id,left,top,width,height,...``, 1-based frames) as {frame: boxes}.

    Raises:
        ConfigError: unreadable file, or a line that is not numbers in that layout (file and line named).
    """
    try:
        text = path.read_text()
    except OSError as err:
        raise ConfigError(f"cannot read ground-truth boxes {str(path)!r}: {err.strerror}") from err
    except UnicodeDecodeError as err:
        raise ConfigError(f"{path}: expected a text file of boxes (MOTChallenge rows), got binary data") from err
    out: dict[int, list[Box]] = {}
    for n, line in enumerate(text.splitlines(), start=1):
        s = line.strip()
        if not s or s.startswith("#"):
            continue
        parts = s.split(",")
        try:
            if len(parts) < BOX_FIELDS:
                raise ValueError(f"{len(parts)} fields")
            frame = int(float(parts[0]))
            left, top, w, h = (float(p) for p in parts[2:6])
        except ValueError as err:
            raise ConfigError(
                f"{path}:{n}: expected 'frame,id,left,top,width,height,...' (numbers), got {s!r}"
            ) from err
        if frame < 1 or not (w > 0 and h > 0) or not all(math.isfinite(v) for v in (left, top, w, h)):
            raise ConfigError(f"{path}:{n}: expected frame >= 1 and a positive finite box, got {s!r}")
        out.setdefault(frame, []).append(Box(left, top, w, h))
    if not out:
        raise ConfigError(f"{path}: no boxes")
    return out


def _array(boxes: Sequence[Box]) -> npt.NDArray[np.float64]:
    """(n, 4) of left, top, right, bottom."""
    if not boxes:
        return np.zeros((0, 4))
    a = np.asarray([(b.left_px, b.top_px, b.width_px, b.height_px) for b in boxes], np.float64)
    a[:, 2:] += a[:, :2]
    return a


def _intersections(a: npt.NDArray[np.float64], b: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    w = np.minimum(a[:, None, 2], b[None, :, 2]) - np.maximum(a[:, None, 0], b[None, :, 0])
    h = np.minimum(a[:, None, 3], b[None, :, 3]) - np.maximum(a[:, None, 1], b[None, :, 1])
    return np.clip(w, 0.0, None) * np.clip(h, 0.0, None)


def _areas(a: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    return (a[:, 2] - a[:, 0]) * (a[:, 3] - a[:, 1])


def iou_matrix(gt: Sequence[Box], det: Sequence[Box]) -> npt.NDArray[np.float64]:
    """(len(gt), len(det)) intersection over union."""
    a, b = _array(gt), _array(det)
    inter = _intersections(a, b)
    union = _areas(a)[:, None] + _areas(b)[None, :] - inter
    return np.where(union > 0, inter / np.maximum(union, 1e-12), 0.0)


BoxBearing = Callable[[float, float], float]
"""Azimuth (rad) of the ray through an image point (u, v)."""


def score_detections(
    truth: Mapping[int, Sequence[Box]],
    found: Mapping[int, Sequence[Detection2D]],
    frames: Sequence[int],
    *,
    thresholds: Sequence[float] = (0.5, 0.3),
    bearing_of: BoxBearing | None = None,
    ignore_above_row: float = 0.0,
) -> list[DetectionScores]:
    """Score the blobs of ``frames`` against the ground truth, one :class:`DetectionScores` per threshold.

    Args:
        truth: ground-truth boxes by frame (frames without an entry hold nobody).
        found: blobs by frame (missing: none).
        frames: the frames to score (those the detector was asked to report on).
        thresholds: IoU a pair needs to match.
        bearing_of: azimuth of the ray through an image point (None: no bearing errors).
        ignore_above_row: an unmatched blob whose bottom is above this row is not a false positive.
    """
    out = [DetectionScores(iou=float(t)) for t in thresholds]
    for k in frames:
        gt = list(truth.get(k, ()))
        det = list(found.get(k, ()))
        boxes = [d.box for d in det]
        iou = iou_matrix(gt, boxes)
        rows, cols = linear_sum_assignment(1.0 - iou) if gt and det else (np.zeros(0, int), np.zeros(0, int))
        gt_a, det_a = _array(gt), _array(boxes)
        inter = _intersections(gt_a, det_a)
        cover = inter / np.maximum(_areas(gt_a), 1e-12)[:, None] if gt else np.zeros((0, len(det)))
        holds = cover >= COVER_FRAC
        merged = holds & (holds.sum(axis=0) >= MERGED_PEOPLE)[None, :]
        for sc in out:
            sc.frames += 1
            sc.objects += len(gt)
            ok = iou[rows, cols] >= sc.iou
            matched_det = set(cols[ok].tolist())
            ignored = sum(1 for j, b in enumerate(boxes) if j not in matched_det and b.bottom_px < ignore_above_row)
            sc.blobs += len(det) - ignored
            sc.matches += int(ok.sum())
            sc.misses += len(gt) - int(ok.sum())
            sc.false_positives += len(det) - ignored - int(ok.sum())
            sc.merged += int(merged.any(axis=1).sum())
            for i in range(len(gt)):
                if not det or cover[i].max() < NO_BLOB_COVER:
                    sc.no_blob += 1
                    continue
                j = int(np.argmax(cover[i]))
                if holds[:, j].sum() <= 1:
                    if boxes[j].width_px >= TOO_WIDE * gt[i].width_px:
                        sc.too_wide += 1
                    sc.bottom_err_px.append(boxes[j].bottom_px - gt[i].bottom_px)
            if bearing_of is None:
                continue
            for i, j in zip(rows[ok].tolist(), cols[ok].tolist(), strict=True):
                g, d = gt[i], det[j]
                truth_az = bearing_of(g.left_px + g.width_px / 2.0, g.bottom_px)
                az = d.bearing_rad
                if not math.isfinite(az):
                    az = bearing_of(d.box.left_px + d.box.width_px / 2.0, d.box.bottom_px)
                sc.bearing_err_deg.append(math.degrees(angle_diff(az, truth_az)))
    return out
