"""The picture of a run: where people went (top view, ground truth beside) and who was followed by which track
(the timeline below), drawn with matplotlib.

Pure drawing (no zenoh, no mcap): decoded messages and ground-truth points in, a PNG out. World x to the right,
y up. The view is sized to where people can be (the site's ``[area]`` or the simulated room when known) or else
to where people were (tracks and ground truth), never to the cameras: a camera far outside is named in a note.

Colours come from matplotlib's colour-blind-safe ``petroff10`` palette. Each person gets one, in order of first
appearance; each track is drawn in the colour of the person it followed in most frames
(:mod:`user_agent.timeline`), and a track that followed nobody in black, dashed. In the timeline a row is a
person: coloured where a track followed them (hatched where that track was not the one that followed them most:
an id they were given after a break or a switch), grey where they were there but missed, and a black bar at
each id switch. A row of one colour is a person followed by one track all along.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import matplotlib as mpl

mpl.use("Agg")  # files only, never a window (before pyplot is imported anywhere)

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.patches import Patch, Polygon, Rectangle
from matplotlib.transforms import Bbox

from common.arrays import FloatArray, U8Image
from common.errors import ConfigError
from common.schema import PairChoice, SensorInfo, TrackSet
from user_agent.groundtruth import GroundTruth
from user_agent.messages import placed_pose
from user_agent.timeline import Timeline, timeline_of_tracks, timeline_with_truth

__all__ = ["PALETTE", "PlotInput", "colours_of", "render_top_view", "save_top_view"]

PALETTE: tuple[str, ...] = tuple(plt.style.library["petroff10"]["axes.prop_cycle"].by_key()["color"])
"""matplotlib's colour-blind-safe ten colours (M. Petroff, 2021), one per person in turn."""
NOBODY = "#000000"
"""A track that followed nobody (a false track)."""
MISSED = "#d9d9d9"
PAD_M = 1.0
"""The top view shows this much floor around where people were (m)."""
PAIR = 2
"""A track localised by a pair of cameras names both."""
LABEL_OFFSETS_PT = [(dx, dy) for r in (4, 10, 18) for dx, dy in ((r, r), (r, -r), (-r, r), (-r, -r), (0, r), (0, -r))]
"""Where a label may go around its point (points), tried in this order until it overlaps no other label."""
MAX_TICK_ROWS = 60
"""A timeline with more rows names only every n-th (and writes no track ids in its bars)."""
MAX_NAMED_PATHS = 40
"""Paths are named at their ends only up to this many in a panel (more are a crowd: the timeline tells them apart)."""
NAMED_OUTSIDE = 6
"""The note on cameras outside the view names at most this many."""


@dataclass(frozen=True, slots=True)
class PlotInput:
    """What the picture shows."""

    tracksets: list[TrackSet]
    sensor_infos: list[SensorInfo]
    pairs: list[PairChoice]
    ground_truth: GroundTruth | None = None
    room_m: tuple[float, float, float, float] | None = None
    """x0, y0, x1, y1 of a simulated room (drawn, and the view when no area is given)."""
    area: list[tuple[float, float]] | None = None
    """The site's ``[area]`` polygon: where people can be (drawn, and the view)."""
    title: str = ""
    states: tuple[str, ...] = ("confirmed", "coasting")
    gt_cameras: dict[str, list[tuple[float, float]]] | None = None
    """True paths of the camera platforms (simulation), drawn in the ground-truth panel."""
    mutual_paths: dict[str, list[tuple[float, float]]] | None = None
    """Mobile cameras as the manager placed them by mutual calibration, drawn in the tracks panel."""
    epoch_ns: int | None = None
    """World time 0 (ground-truth frame 1); None: the first TrackSet, and the timeline has no ground truth."""
    fps: float | None = None
    """The ground truth's frame rate (needed to line it up with the tracks)."""
    threshold_m: float = 0.5
    """A track farther than this from a person is not following them (as in ``agent evaluate``)."""
    scored_area: FloatArray | None = None
    """Where the ground truth annotates people (tracks outside are not scored, as in ``agent evaluate``)."""
    scored_from_s: float = 0.0
    """World time from which the run is scored (the warm-up before it is shaded)."""


def _timeline(inp: PlotInput) -> Timeline:
    epoch = inp.epoch_ns if inp.epoch_ns is not None else min((t.stamp_ns for t in inp.tracksets), default=0)
    if inp.ground_truth is not None and inp.epoch_ns is not None and inp.fps:
        return timeline_with_truth(
            inp.tracksets,
            inp.ground_truth,
            epoch_ns=inp.epoch_ns,
            fps=inp.fps,
            threshold_m=inp.threshold_m,
            area=inp.scored_area,
            states=inp.states,
        )
    stamps = sorted({t.stamp_ns for t in inp.tracksets})
    period = float(np.median(np.diff(stamps))) / 1e9 * 1.5 if len(stamps) > 1 else 1.0
    return timeline_of_tracks(inp.tracksets, epoch_ns=epoch, period_s=max(period, 1e-3), states=inp.states)


def colours_of(tl: Timeline) -> tuple[dict[str, str], dict[str, str]]:
    """(row -> colour, track -> colour): rows in turn from the palette; a track like the person it followed."""
    rows = {r: PALETTE[i % len(PALETTE)] for i, r in enumerate(tl.rows)}
    if not tl.with_truth:
        return rows, dict(rows)
    return rows, {t: rows[p] for t, p in tl.track_person.items() if p in rows}


def _extent(inp: PlotInput) -> tuple[float, float, float, float]:
    """The floor shown: the area, else the room, else where people were (tracks and ground truth) with a margin."""
    if inp.area:
        xs, ys = [p[0] for p in inp.area], [p[1] for p in inp.area]
        return (min(xs) - 0.5, min(ys) - 0.5, max(xs) + 0.5, max(ys) + 0.5)
    if inp.room_m is not None:
        x0, y0, x1, y1 = inp.room_m
        if not (x1 > x0 and y1 > y0):
            raise ConfigError(f"plot extent must be non-empty: the room is x {x0}..{x1}, y {y0}..{y1}")
        return (x0 - 0.3, y0 - 0.3, x1 + 0.3, y1 + 0.3)
    pts = [(t.x_m, t.y_m) for ts in inp.tracksets for t in ts.tracks if t.state in inp.states]
    if inp.ground_truth is not None:
        pts = [(p.x_m, p.y_m) for f in inp.ground_truth.frames.values() for p in f] or pts
    if not pts:
        pts = [(p.x_m, p.y_m) for i in inp.sensor_infos if (p := placed_pose(i)) is not None]
    if not pts:
        return (0.0, 0.0, 1.0, 1.0)
    arr = np.asarray(pts)
    # People's extent, robust to a few wild tracks: the ground truth whole, tracks within their 1st-99th percentile.
    lo, hi = np.percentile(arr, 1, axis=0), np.percentile(arr, 99, axis=0)
    if inp.ground_truth is not None and inp.ground_truth.frames:
        lo, hi = arr.min(axis=0), arr.max(axis=0)
    return (float(lo[0]) - PAD_M, float(lo[1]) - PAD_M, float(hi[0]) + PAD_M, float(hi[1]) + PAD_M)


def _inside(ext: tuple[float, float, float, float], x: float, y: float) -> bool:
    return ext[0] <= x <= ext[2] and ext[1] <= y <= ext[3]


def _floor(ax: Axes, inp: PlotInput, ext: tuple[float, float, float, float], heading: str) -> None:
    ax.set_xlim(ext[0], ext[2])
    ax.set_ylim(ext[1], ext[3])
    ax.set_aspect("equal")
    ax.grid(True, color="#eeeeee", linewidth=0.6)
    ax.set_axisbelow(True)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(heading, fontsize=10, loc="left")
    if inp.area:
        ax.add_patch(Polygon(inp.area, closed=True, fill=False, edgecolor="#555555", linestyle="--", linewidth=1))
    if inp.room_m is not None:
        x0, y0, x1, y1 = inp.room_m
        ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, edgecolor="#555555", linewidth=1.5))


def _cameras(ax: Axes, inp: PlotInput, ext: tuple[float, float, float, float], labels: list[_Label]) -> None:
    poses = {i.sensor_id: i for i in inp.sensor_infos if placed_pose(i) is not None}
    used: Counter[tuple[str, str]] = Counter()
    for pc in inp.pairs:
        for e in pc.choices:
            a, b = sorted((e.sensor_a, e.sensor_b))
            used[(a, b)] += 1
    if not inp.pairs:
        for ts in inp.tracksets:
            for tr in ts.tracks:
                if len(tr.sensors) >= PAIR:
                    a, b = sorted(tr.sensors[:2])
                    used[(a, b)] += 1
    top = max(used.values(), default=1)
    outside = []
    for (a, b), n in used.items():
        pa, pb = (placed_pose(poses[s]) if s in poses else None for s in (a, b))
        if pa is not None and pb is not None and _inside(ext, pa.x_m, pa.y_m) and _inside(ext, pb.x_m, pb.y_m):
            ax.plot([pa.x_m, pb.x_m], [pa.y_m, pb.y_m], color="#d0d0d0", linewidth=0.5 + 2.5 * n / top, zorder=1)
    for sid, info in sorted(poses.items()):
        p = placed_pose(info)
        assert p is not None
        if not _inside(ext, p.x_m, p.y_m):
            outside.append(sid)
            continue
        marker = "o" if info.kind == "panoramic" else "^"
        ax.plot(p.x_m, p.y_m, marker=marker, markersize=7, markerfacecolor="white", markeredgecolor="#444444", zorder=3)
        if info.kind == "panoramic":
            ax.plot([p.x_m, p.x_m + 0.35 * math.cos(p.yaw_rad)], [p.y_m, p.y_m + 0.35 * math.sin(p.yaw_rad)],
                    color="#444444", linewidth=0.8, zorder=3)  # fmt: skip
        labels.append(_Label(p.x_m, p.y_m, sid, "#444444"))
    if outside:
        n = NAMED_OUTSIDE
        shown = ", ".join(outside[:n]) + (f" and {len(outside) - n} more" if len(outside) > n else "")
        ax.text(0.01, 0.01, f"cameras outside this view: {shown}", transform=ax.transAxes, fontsize=7,
                color="#444444", va="bottom")  # fmt: skip


def _platforms(ax: Axes, paths: dict[str, list[tuple[float, float]]], labels: list[_Label]) -> None:
    for sid, pts in sorted(paths.items()):
        if pts:
            arr = np.asarray(pts)
            ax.plot(arr[:, 0], arr[:, 1], color="#888888", linewidth=0.8, zorder=2)
            ax.plot(*arr[-1], marker="o", markersize=7, markerfacecolor="white", markeredgecolor="#444444", zorder=3)
            labels.append(_Label(float(arr[-1, 0]), float(arr[-1, 1]), sid, "#444444"))


@dataclass(frozen=True, slots=True)
class _Label:
    x: float
    y: float
    text: str
    colour: str


def _path(ax: Axes, pts: Sequence[tuple[float, float]], colour: str, text: str, dashed: bool) -> _Label:
    """One walked path: a line, a dot where it began, a ring where it ended (labelled there)."""
    arr = np.asarray(pts)
    style = (0, (3, 2)) if dashed else "-"
    ax.plot(arr[:, 0], arr[:, 1], color=colour, linewidth=1.4, linestyle=style, zorder=4)
    ax.plot(*arr[0], marker="o", markersize=3, color=colour, zorder=5)
    ax.plot(*arr[-1], marker="o", markersize=6, markerfacecolor="white", markeredgecolor=colour, zorder=5)
    return _Label(float(arr[-1, 0]), float(arr[-1, 1]), text, colour)


def _place_labels(fig: Figure, ax: Axes, labels: list[_Label], taken: list[Bbox]) -> int:
    """Write each label next to its point where it overlaps no label already placed (in any panel); returns how
    many found no such place (left out)."""
    renderer = fig.canvas.get_renderer()  # type: ignore[attr-defined]
    frame = ax.get_window_extent(renderer)
    left_out = 0
    for lab in labels:
        if not _inside(_ext(ax), lab.x, lab.y):
            continue
        for dx, dy in LABEL_OFFSETS_PT:
            text = ax.annotate(lab.text, (lab.x, lab.y), xytext=(dx, dy), textcoords="offset points", fontsize=7,
                               color=lab.colour, ha="left" if dx >= 0 else "right",
                               va="bottom" if dy >= 0 else "top", zorder=6,
                               bbox={"boxstyle": "square,pad=0.1", "facecolor": "white", "alpha": 0.7,
                                     "linewidth": 0})  # fmt: skip
            box = text.get_window_extent(renderer)
            inside = frame.contains(box.x0, box.y0) and frame.contains(box.x1, box.y1)
            if inside and not any(box.overlaps(b) for b in taken):
                taken.append(box.expanded(1.1, 1.2))
                break
            text.remove()
        else:
            left_out += 1
    return left_out


def _ext(ax: Axes) -> tuple[float, float, float, float]:
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    return (x0, y0, x1, y1)


def _track_paths(inp: PlotInput) -> dict[str, list[tuple[float, float]]]:
    paths: dict[str, list[tuple[float, float]]] = {}
    for ts in inp.tracksets:
        for tr in ts.tracks:
            if tr.state in inp.states:
                paths.setdefault(tr.track_id, []).append((tr.x_m, tr.y_m))
    return paths


def bar_names(track_ids: Sequence[str]) -> dict[str, str]:
    """What a timeline bar writes for each track id: its number (``{manager}-{n}``) when one manager minted them all,
    else the id without the managers' common leading part (``mgr-nw-7``, ``mgr-ne-7`` -> ``nw-7``, ``ne-7``)."""
    ids = sorted(set(track_ids))
    minted = {tid.rsplit("-", 1)[0] for tid in ids}
    if len(minted) <= 1:
        return {tid: tid.rsplit("-", 1)[-1] for tid in ids}
    common = 0
    for parts in zip(*(tid.split("-") for tid in ids), strict=False):
        if len(set(parts)) > 1:
            break
        common += 1
    return {tid: "-".join(tid.split("-")[common:]) for tid in ids}


def _draw_timeline(
    ax: Axes, tl: Timeline, rows_col: dict[str, str], tracks_col: dict[str, str], inp: PlotInput
) -> None:
    """One row per person (or track), top to bottom in order of first appearance."""
    index = {r: i for i, r in enumerate(tl.rows)}
    width_s = max((s.t1_s for s in tl.spans), default=1.0) - min((s.t0_s for s in tl.spans), default=0.0)
    px_per_s = ax.get_window_extent().width / max(width_s, 1e-9)
    bars = bar_names([s.track_id for s in tl.spans if s.track_id])
    for s in tl.spans:
        y = index[s.row]
        if not s.track_id:
            ax.broken_barh([(s.t0_s, s.t1_s - s.t0_s)], (y - 0.35, 0.7), facecolors=MISSED, edgecolor="none")
            continue
        colour = tracks_col.get(s.track_id, NOBODY)
        # Solid: the person's own track (it followed them most, and they are whom it followed most).
        own = tl.main_track.get(s.row) == s.track_id and tl.track_person.get(s.track_id) == s.row
        other_id = tl.with_truth and not own
        ax.broken_barh([(s.t0_s, s.t1_s - s.t0_s)], (y - 0.35, 0.7), facecolors=colour,
                       edgecolor="white" if other_id else "none", hatch="////" if other_id else None,
                       linewidth=0)  # fmt: skip
        short = bars[s.track_id]
        if (s.t1_s - s.t0_s) * px_per_s > 8 * len(short) + 8 and len(tl.rows) <= MAX_TICK_ROWS:
            box = {"boxstyle": "round,pad=0.15", "facecolor": "white", "alpha": 0.75, "linewidth": 0}
            ax.text((s.t0_s + s.t1_s) / 2, y, short, ha="center", va="center", fontsize=7, color="#222222", bbox=box)
    half = 0.5 / inp.fps if inp.fps else 0.0  # a switch is at the start of the frame whose span it begins
    for sw in tl.switches:
        y = index[sw.row]
        ax.plot([sw.t_s - half] * 2, [y - 0.5, y + 0.5], color="black", linewidth=2.0, solid_capstyle="butt")
    if inp.scored_from_s > 0:
        ax.axvline(inp.scored_from_s, color="#444444", linestyle=":", linewidth=1.2, zorder=0)
        ax.text(inp.scored_from_s, -0.75, " scored from here (before: warm-up)", fontsize=7, color="#444444",
                va="center")  # fmt: skip
    ax.set_ylim(len(tl.rows) - 0.5, -1.0)
    step = max(1, math.ceil(len(tl.rows) / MAX_TICK_ROWS))
    ticks = list(range(0, len(tl.rows), step))
    names = [f"#{tl.rows[i]}" if tl.with_truth else tl.rows[i] for i in ticks]
    ax.set_yticks(ticks, names, fontsize=7 if len(ticks) > MAX_TICK_ROWS // 3 else 8)
    for tick, i in zip(ax.get_yticklabels(), ticks, strict=True):
        tick.set_color(rows_col[tl.rows[i]])
    ax.set_xlabel("time (s)")
    ax.grid(True, axis="x", color="#eeeeee", linewidth=0.6)
    ax.set_axisbelow(True)
    if tl.with_truth:
        head = timeline_head(tl, inp.scored_from_s)
        legend = [
            Patch(facecolor=PALETTE[0], label="their own track"),
            Patch(facecolor=PALETTE[0], hatch="////", edgecolor="white", label="another id (its colour: whose track)"),
            Patch(facecolor=MISSED, label="there, not followed"),
            Patch(facecolor="black", label="id switch"),
        ]
    else:
        head = "tracks over time: one row per track (no ground truth)"
        legend = [
            Patch(facecolor=PALETTE[0], label="published"),
            Patch(facecolor="white", edgecolor="#999999", label="gap: not published"),
        ]
    ax.set_title(head, fontsize=10, loc="left", pad=22)
    ax.legend(handles=legend, loc="lower right", bbox_to_anchor=(1.0, 1.0), fontsize=7, frameon=False,
              ncol=len(legend), borderaxespad=0.2)  # fmt: skip


def timeline_head(tl: Timeline, scored_from_s: float) -> str:
    """The timeline's title: its id switches counted as the run's score counts them, from the end of the warm-up
    (``scored_from_s``), those before said apart."""
    n = sum(1 for sw in tl.switches if sw.t_s >= scored_from_s)
    head = f"who was followed by which track: one row per person, {n} id switch{'' if n == 1 else 'es'}"
    if len(tl.switches) > n:
        head += f" ({len(tl.switches) - n} more in the warm-up)"
    return head


def _figure(inp: PlotInput) -> Figure:
    ext = _extent(inp)
    if not (ext[2] > ext[0] and ext[3] > ext[1]):
        raise ConfigError(f"plot extent must be non-empty, got x {ext[0]}..{ext[2]}, y {ext[1]}..{ext[3]}")
    tl = _timeline(inp)
    rows_col, tracks_col = colours_of(tl)
    panels = 2 if inp.ground_truth is not None else 1
    panel_w = 6.0
    panel_h = min(max(panel_w * (ext[3] - ext[1]) / (ext[2] - ext[0]), 3.0), 9.0)
    rows = max(len(tl.rows), 1)
    line_h = 0.2 if rows <= MAX_TICK_ROWS else max(0.05, 12.0 / rows)
    time_h = min(max(line_h * rows + 1.2, 2.2), 16.0)
    fig_w = panel_w * panels + 1.6
    fig_h = panel_h + time_h + 2.4
    fig = plt.figure(figsize=(fig_w, fig_h), dpi=100)
    grid = fig.add_gridspec(2, panels, height_ratios=[panel_h, time_h], left=0.9 / fig_w, right=1 - 0.5 / fig_w,
                            top=1 - 0.75 / fig_h, bottom=0.5 / fig_h, hspace=1.2 / ((panel_h + time_h) / 2),
                            wspace=0.15)  # fmt: skip
    if inp.title:
        fig.suptitle(inp.title, x=0.9 / fig_w, y=1 - 0.15 / fig_h, ha="left", va="top", fontsize=12)
    ax_tracks = fig.add_subplot(grid[0, 0])
    heading = "tracks, coloured like the person each followed most" if tl.with_truth else "tracks, one colour each"
    _floor(ax_tracks, inp, ext, heading)
    labels: list[_Label] = []
    _cameras(ax_tracks, inp, ext, labels)
    if inp.mutual_paths:
        _platforms(ax_tracks, inp.mutual_paths, labels)
    paths = _track_paths(inp)
    track_labels = [
        _path(ax_tracks, pts, tracks_col.get(tid, NOBODY), tid, tid not in tracks_col) for tid, pts in paths.items()
    ]
    if len(paths) > MAX_NAMED_PATHS:  # a crowd: the paths show where people went, the timeline who was who
        track_labels = []
    ax_time = fig.add_subplot(grid[1, :])
    _draw_timeline(ax_time, tl, rows_col, tracks_col, inp)
    truth_labels: list[_Label] = []
    if inp.ground_truth is not None:
        ax_truth = fig.add_subplot(grid[0, 1], sharex=ax_tracks, sharey=ax_tracks)
        _floor(ax_truth, inp, ext, "ground truth, one colour per person")
        if inp.gt_cameras:
            _platforms(ax_truth, inp.gt_cameras, truth_labels)
        else:
            _cameras(ax_truth, inp, ext, truth_labels)
        for pid in inp.ground_truth.person_ids:
            pts = [(p.x_m, p.y_m) for p in inp.ground_truth.track_of(pid)]
            label = _path(ax_truth, pts, rows_col.get(pid, NOBODY), f"#{pid}", pid not in rows_col)
            if len(inp.ground_truth.person_ids) <= MAX_NAMED_PATHS:
                truth_labels.append(label)
    fig.canvas.draw()  # every panel is in place: the layout is fixed and labels can be measured
    taken: list[Bbox] = []
    _place_labels(fig, ax_tracks, labels + track_labels, taken)
    if inp.ground_truth is not None:
        _place_labels(fig, ax_truth, truth_labels, taken)
    return fig


def render_top_view(inp: PlotInput) -> U8Image:
    """The picture as an RGB image (rows, columns, 3)."""
    fig = _figure(inp)
    try:
        fig.canvas.draw()
        rgba = np.asarray(fig.canvas.buffer_rgba())  # type: ignore[attr-defined]
        return np.ascontiguousarray(rgba[:, :, :3])
    finally:
        plt.close(fig)


def save_top_view(inp: PlotInput, out: str | Path) -> Path:
    """Render and write the PNG; returns its path.

    Raises:
        ConfigError: if the file cannot be written.
    """
    p = Path(out)
    if p.suffix.lower() != ".png":
        raise ConfigError(f"{p}: the picture is a PNG: name it .png")
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise ConfigError(f"{p}: cannot write image: {err.strerror}") from err
    fig = _figure(inp)
    try:
        fig.savefig(p, dpi=100)
    except OSError as err:
        raise ConfigError(f"{p}: cannot write image: {err.strerror}") from err
    finally:
        plt.close(fig)
    return p
