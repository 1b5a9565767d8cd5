"""Top view of a run: room, cameras, their pairings, tracks coloured by id, and ground truth beside.

Pure drawing with OpenCV (no zenoh, no mcap): takes decoded messages and
ground-truth points, writes a PNG. World x to the right, y up.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from common.arrays import U8Image
from common.errors import ConfigError
from common.schema import PairChoice, SensorInfo, TrackSet
from user_agent.colors import id_color_bgr
from user_agent.groundtruth import GroundTruth
from user_agent.messages import placed_pose

__all__ = ["PlotInput", "render_top_view", "save_top_view"]

PAIR = 2
"""A track localised by a pair of cameras names both."""


_BG = (255, 255, 255)
_GRID = (230, 230, 230)
_INK = (40, 40, 40)
_ROOM = (90, 90, 90)
_PAIR = (170, 170, 170)


@dataclass(frozen=True, slots=True)
class PlotInput:
    """What the top view shows."""

    tracksets: list[TrackSet]
    sensor_infos: list[SensorInfo]
    pairs: list[PairChoice]
    ground_truth: GroundTruth | None = None
    room_m: tuple[float, float, float, float] | None = None
    """x0, y0, x1, y1 of the room (None: fit the data)."""
    title: str = ""
    states: tuple[str, ...] = ("confirmed", "coasting")
    gt_cameras: dict[str, list[tuple[float, float]]] | None = None
    """True paths of the camera platforms (simulation), drawn in the ground-truth panel."""
    mutual_paths: dict[str, list[tuple[float, float]]] | None = None
    """Mobile cameras as the manager placed them by mutual calibration, drawn in the tracks panel."""


@dataclass(frozen=True, slots=True)
class _View:
    x0: float
    y0: float
    x1: float
    y1: float
    scale: float
    margin: int = 50

    @property
    def size(self) -> tuple[int, int]:
        w = int((self.x1 - self.x0) * self.scale) + 2 * self.margin
        h = int((self.y1 - self.y0) * self.scale) + 2 * self.margin + 30
        return w, h

    def px(self, x: float, y: float) -> tuple[int, int]:
        _, h = self.size
        return (
            round(self.margin + (x - self.x0) * self.scale),
            round(h - self.margin - (y - self.y0) * self.scale),
        )


def _extent(inp: PlotInput) -> tuple[float, float, float, float]:
    if inp.room_m is not None:
        return inp.room_m
    xs: list[float] = []
    ys: list[float] = []
    for info in inp.sensor_infos:
        pose = placed_pose(info)
        if pose is not None:
            xs.append(pose.x_m)
            ys.append(pose.y_m)
    for ts in inp.tracksets:
        for tr in ts.tracks:
            xs.append(tr.x_m)
            ys.append(tr.y_m)
    if inp.ground_truth is not None:
        for pts in inp.ground_truth.frames.values():
            for p in pts:
                xs.append(p.x_m)
                ys.append(p.y_m)
    if not xs:
        return (0.0, 0.0, 1.0, 1.0)
    pad = 0.5
    return (min(xs) - pad, min(ys) - pad, max(xs) + pad, max(ys) + pad)


def _panel(view: _View, inp: PlotInput, heading: str) -> U8Image:
    w, h = view.size
    img = np.full((h, w, 3), _BG, np.uint8)
    for gx in range(math.ceil(view.x0), math.floor(view.x1) + 1):
        cv2.line(img, view.px(gx, view.y0), view.px(gx, view.y1), _GRID, 1)
        cv2.putText(img, f"{gx}", view.px(gx, view.y0), cv2.FONT_HERSHEY_SIMPLEX, 0.35, _INK, 1, cv2.LINE_AA)
    for gy in range(math.ceil(view.y0), math.floor(view.y1) + 1):
        cv2.line(img, view.px(view.x0, gy), view.px(view.x1, gy), _GRID, 1)
        x, y = view.px(view.x0, gy)
        cv2.putText(img, f"{gy}", (x - 22, y + 4), cv2.FONT_HERSHEY_SIMPLEX, 0.35, _INK, 1, cv2.LINE_AA)
    if inp.room_m is not None:
        cv2.rectangle(img, view.px(view.x0, view.y1), view.px(view.x1, view.y0), _ROOM, 2)
    cv2.putText(img, heading, (view.margin, 24), cv2.FONT_HERSHEY_SIMPLEX, 0.6, _INK, 1, cv2.LINE_AA)
    return img


def _cameras(img: U8Image, view: _View, inp: PlotInput) -> None:
    poses = {i.sensor_id: i for i in inp.sensor_infos if placed_pose(i) is not None}
    used: Counter[tuple[str, str]] = Counter()
    for pc in inp.pairs:
        for e in pc.choices:
            a, b = sorted((e.sensor_a, e.sensor_b))
            used[(a, b)] += 1
    for ts in inp.tracksets:
        for tr in ts.tracks:
            if len(tr.sensors) >= PAIR and not inp.pairs:
                a, b = sorted(tr.sensors[:2])
                used[(a, b)] += 1
    top = max(used.values(), default=1)
    for (a, b), n in used.items():
        if a in poses and b in poses:
            pa, pb = poses[a].pose, poses[b].pose
            assert pa is not None and pb is not None
            thick = 1 + int(5 * n / top)
            cv2.line(img, view.px(pa.x_m, pa.y_m), view.px(pb.x_m, pb.y_m), _PAIR, thick, cv2.LINE_AA)
    for sid, info in poses.items():
        p = info.pose
        assert p is not None
        c = view.px(p.x_m, p.y_m)
        r = max(4, int(max(info.body_radius_m, 0.1) * view.scale))
        cv2.circle(img, c, r, (60, 60, 60), 2, cv2.LINE_AA)
        if info.kind == "panoramic":
            tip = view.px(p.x_m + 0.35 * math.cos(p.yaw_rad), p.y_m + 0.35 * math.sin(p.yaw_rad))
            cv2.line(img, c, tip, (60, 60, 60), 1, cv2.LINE_AA)
        else:
            cv2.drawMarker(img, c, (60, 60, 60), cv2.MARKER_TRIANGLE_UP, 12, 2)
        _label(img, sid, (c[0] + r + 2, c[1] - r))


def _label(img: U8Image, text: str, at: tuple[int, int], color: tuple[int, int, int] = _INK) -> None:
    """Text that stays inside the image (moved left of the point near the right edge)."""
    (tw, _), _ = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, 0.4, 1)
    x = at[0] if at[0] + tw < img.shape[1] - 2 else at[0] - tw - 24
    cv2.putText(img, text, (x, at[1]), cv2.FONT_HERSHEY_SIMPLEX, 0.4, color, 1, cv2.LINE_AA)


def _platforms(img: U8Image, view: _View, paths: dict[str, list[tuple[float, float]]]) -> None:
    for sid, pts in sorted(paths.items()):
        if not pts:
            continue
        arr = np.array([view.px(x, y) for x, y in pts], np.int32).reshape(-1, 1, 2)
        cv2.polylines(img, [arr], False, (120, 120, 120), 1, cv2.LINE_AA)
        c = view.px(*pts[-1])
        cv2.circle(img, c, max(4, int(0.18 * view.scale)), (60, 60, 60), 2, cv2.LINE_AA)
        _label(img, sid, (c[0] + 10, c[1] - 10))


def _polyline(img: U8Image, view: _View, pts: list[tuple[float, float]], ident: str, label: str) -> None:
    if not pts:
        return
    col = id_color_bgr(ident)
    arr = np.array([view.px(x, y) for x, y in pts], np.int32).reshape(-1, 1, 2)
    cv2.polylines(img, [arr], False, col, 2, cv2.LINE_AA)
    cv2.circle(img, view.px(*pts[0]), 3, col, -1, cv2.LINE_AA)
    end = view.px(*pts[-1])
    cv2.circle(img, end, 5, col, 2, cv2.LINE_AA)
    _label(img, label, (end[0] + 6, end[1] + 4), col)


def render_top_view(inp: PlotInput, max_px: int = 900) -> U8Image:
    """The top view as a BGR image: tracks (and ground truth beside, when given)."""
    x0, y0, x1, y1 = _extent(inp)
    if not (x1 > x0 and y1 > y0):
        raise ConfigError(f"plot extent must be non-empty, got x {x0}..{x1}, y {y0}..{y1}")
    scale = min(max_px / (x1 - x0), max_px / (y1 - y0), 120.0)
    view = _View(x0, y0, x1, y1, scale)
    left = _panel(view, inp, "tracks" + (f"  {inp.title}" if inp.title else ""))
    _cameras(left, view, inp)
    if inp.mutual_paths:
        _platforms(left, view, inp.mutual_paths)
    paths: dict[str, list[tuple[float, float]]] = {}
    for ts in inp.tracksets:
        for tr in ts.tracks:
            if tr.state in inp.states:
                paths.setdefault(tr.track_id, []).append((tr.x_m, tr.y_m))
    for tid, pts in sorted(paths.items()):
        _polyline(left, view, pts, tid, tid)
    if inp.ground_truth is None:
        return left
    right = _panel(view, inp, "ground truth")
    if inp.gt_cameras:
        _platforms(right, view, inp.gt_cameras)
    else:
        _cameras(right, view, inp)
    for pid in inp.ground_truth.person_ids:
        pts = [(p.x_m, p.y_m) for p in inp.ground_truth.track_of(pid)]
        _polyline(right, view, pts, f"gt-{pid}", f"#{pid}")
    gap = np.full((left.shape[0], 12, 3), (200, 200, 200), np.uint8)
    return np.hstack([left, gap, right])


def save_top_view(inp: PlotInput, out: str | Path, max_px: int = 900) -> Path:
    """Render and write the PNG; returns its path.

    Raises:
        ConfigError: if the file cannot be written.
    """
    p = Path(out)
    p.parent.mkdir(parents=True, exist_ok=True)
    img = render_top_view(inp, max_px)
    try:
        ok = cv2.imwrite(str(p), img)
    except cv2.error as err:  # OpenCV raises for an extension it has no writer for
        raise ConfigError(f"{p}: cannot write image (is the extension .png?)") from err
    if not ok:
        raise ConfigError(f"{p}: cannot write image (is the extension .png?)")
    return p
