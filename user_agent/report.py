"""Score and plot a recording: the shared back end of ``evaluate``, ``plot`` and ``demo``."""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from common.arrays import FloatArray
from common.errors import ConfigError
from common.schema import TrackSet
from user_agent.evaluate import HypPoint, MotMetrics, evaluate_positions, hypotheses_from_tracksets, unseen_spans
from user_agent.groundtruth import GroundTruth, read_gt_csv
from user_agent.plot import PlotInput, save_top_view
from user_agent.recording import Recording, load_recording

MIN_POLYGON = 3
"""An area has at least three corners."""

__all__ = ["Scored", "area_of", "plot_recording", "room_of", "score_recording", "score_tracksets", "write_tracks_csv"]


@dataclass(frozen=True, slots=True)
class Scored:
    metrics: MotMetrics
    tracks_published: int
    """Distinct confirmed/coasting track ids in the recording."""
    tracksets: int
    frames_scored: int
    hypotheses: dict[int, list[HypPoint]] = field(default_factory=dict)
    """The tracks' positions at each scored ground-truth frame (what was scored; e.g. for a CSV export)."""
    unseen_s: float = 0.0
    """Seconds of the run whose TrackSets the recording lost (not scored; see evaluate.unseen_spans)."""


def score_recording(
    rec: Recording,
    gt: GroundTruth,
    *,
    threshold_m: float = 0.5,
    epoch_ns: int | None = None,
    fps: float | None = None,
    max_gap_s: float = 0.25,
    start_ns: int | None = None,
    on_events: Callable[[int, list[tuple[str, str, str, float]]], None] | None = None,
    area: FloatArray | None = None,
) -> Scored:
    """Evaluate a recording's TrackSets against ground truth (``area``: see :func:`score_tracksets`).

    ``epoch_ns``, ``fps`` and ``start_ns`` (end of the run's warm-up) default
    to the recording's metadata (written by the recorder from the site,
    ``PANOSTEREO_EPOCH_NS`` and, for a demo run, its warm-up). ``on_events`` is called with each scored
    frame's events (see :func:`~user_agent.evaluate.evaluate_positions`), to see where frames are lost.
    Frames whose TrackSets the recording lost (gaps in a manager's TrackSet numbers) are not scored:
    ``Scored.unseen_s`` says how much of the run that was.

    Raises:
        ConfigError: if the epoch or fps is neither given nor in the recording.
    """
    epoch = epoch_ns if epoch_ns is not None else rec.meta_int("epoch_ns", -1)
    rate = fps if fps is not None else rec.meta_float("fps", -1.0)
    if epoch < 0:
        raise ConfigError("the recording has no epoch_ns metadata: pass --epoch-ns (the run's PANOSTEREO_EPOCH_NS)")
    if rate <= 0:
        raise ConfigError("the recording has no fps metadata: pass --fps (the ground truth's frame rate)")
    start = start_ns if start_ns is not None else rec.meta_int("score_from_ns", -1)
    return score_tracksets(
        rec.tracksets,
        gt,
        epoch_ns=epoch,
        fps=rate,
        threshold_m=threshold_m,
        max_gap_s=max_gap_s,
        start_ns=start if start >= 0 else None,
        on_events=on_events,
        area=area,
    )


def score_tracksets(
    tracksets: Sequence[TrackSet],
    gt: GroundTruth,
    *,
    epoch_ns: int,
    fps: float,
    threshold_m: float = 0.5,
    max_gap_s: float = 0.25,
    start_ns: int | None = None,
    on_events: Callable[[int, list[tuple[str, str, str, float]]], None] | None = None,
    area: FloatArray | None = None,
) -> Scored:
    """Evaluate TrackSets against ground truth whose frame ``k`` is ``epoch_ns + (k - 1) / fps``.

    Every ground-truth frame from the first one (or ``start_ns``) to the last TrackSet is scored
    (:func:`~user_agent.evaluate.hypotheses_from_tracksets`), except where the TrackSets' numbering shows the
    recording lost some (:func:`~user_agent.evaluate.unseen_spans`). ``area``: where the ground truth annotates people
    (:meth:`~user_agent.groundtruth.GroundTruth.area`); tracks outside it are not scored.
    """
    unseen = unseen_spans(tracksets, max_gap_s)
    hyps, frames = hypotheses_from_tracksets(
        tracksets, epoch_ns, fps, gt.frame_numbers, max_gap_s=max_gap_s, start_ns=start_ns, skip=unseen
    )
    metrics = evaluate_positions(gt, hyps, threshold_m, frames=frames, on_events=on_events, area=area)
    published = {t.track_id for ts in tracksets for t in ts.tracks if t.state in ("confirmed", "coasting")}
    unseen_s = sum(b - a for a, b in unseen) / 1e9
    return Scored(metrics, len(published), len(tracksets), len(frames), hyps, unseen_s)


def room_of(rec: Recording) -> tuple[float, float, float, float] | None:
    """The room rectangle from the recording's metadata, if the recorder knew the site."""
    try:
        return (
            float(rec.metadata.get("room_x0_m", 0.0)),
            float(rec.metadata.get("room_y0_m", 0.0)),
            float(rec.metadata["room_x_m"]),
            float(rec.metadata["room_y_m"]),
        )
    except (KeyError, ValueError):
        return None


def area_of(rec: Recording) -> list[tuple[float, float]] | None:
    """The site's ``[area]`` polygon from the recording's metadata (``area``: JSON corners), if it was stored."""
    raw = rec.metadata.get("area")
    if not raw:
        return None
    try:
        pts = [(float(x), float(y)) for x, y in json.loads(raw)]
    except (ValueError, TypeError) as err:
        raise ConfigError(f"the recording's area metadata is not a list of [x, y] corners: {raw[:80]!r}") from err
    return pts if len(pts) >= MIN_POLYGON else None


def plot_recording(
    rec: Recording | str | Path,
    out: str | Path,
    ground_truth: GroundTruth | str | Path | None = None,
    title: str = "",
    gt_cameras: dict[str, list[tuple[float, float]]] | None = None,
    *,
    threshold_m: float = 0.5,
    area: list[tuple[float, float]] | None = None,
    scored_area: FloatArray | None = None,
    epoch_ns: int | None = None,
    fps: float | None = None,
) -> Path:
    """Write the picture of a recording: top view (ground truth beside it when given) and the timeline.

    ``area`` (the site's ``[area]`` polygon) defaults to the one the recording stores; ``threshold_m`` and
    ``scored_area`` are the scoring's, so the timeline shows what ``agent evaluate`` counts; ``epoch_ns`` and
    ``fps`` (ground-truth frame ``k`` at ``(k - 1) / fps`` after the epoch) default to the recording's metadata:
    without them the ground truth cannot be lined up, and the timeline has one row per track.
    """
    r = rec if isinstance(rec, Recording) else load_recording(rec)
    gt = read_gt_csv(ground_truth) if isinstance(ground_truth, str | Path) else ground_truth
    epoch = epoch_ns if epoch_ns is not None else r.meta_int("epoch_ns", -1)
    fps = fps if fps is not None else r.meta_float("fps", -1.0)
    if gt is not None and r.tracksets and epoch >= 0 and fps > 0:
        # Only the recorded span of the ground truth, so both panels show the same time window.
        t0 = (r.tracksets[0].stamp_ns - epoch) / 1e9
        t1 = (r.tracksets[-1].stamp_ns - epoch) / 1e9
        keep = {k: v for k, v in gt.frames.items() if t0 - 0.5 <= (k - 1) / fps <= t1 + 0.5}
        gt = GroundTruth(keep, gt.source)
    score_from = r.meta_int("score_from_ns", -1)
    inp = PlotInput(
        tracksets=r.tracksets,
        sensor_infos=list(r.sensor_infos.values()),
        pairs=r.pairs,
        ground_truth=gt,
        room_m=room_of(r),
        area=area if area is not None else area_of(r),
        title=title,
        gt_cameras=gt_cameras,
        mutual_paths=r.mutual_paths,
        epoch_ns=epoch if epoch >= 0 else None,
        fps=fps if fps > 0 else None,
        threshold_m=threshold_m,
        scored_area=scored_area,
        scored_from_s=(score_from - epoch) / 1e9 if score_from >= 0 and epoch >= 0 else 0.0,
    )
    return save_top_view(inp, out)


def write_tracks_csv(path: str | Path, hypotheses: dict[int, list[HypPoint]]) -> int:
    """Write scored track positions (:attr:`Scored.hypotheses`) as ``frame,id,x_m,y_m``, for other scorers.

    The frames are the ground truth's (1-based at its fps), each track at the frame's instant.

    Returns:
        The number of rows written.
    """
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    n = 0
    with p.open("w", encoding="utf-8") as fh:
        fh.write("frame,id,x_m,y_m\n")
        for k in sorted(hypotheses):
            for h in sorted(hypotheses[k], key=lambda h: h.track_id):
                fh.write(f"{k},{h.track_id},{h.x_m:.4f},{h.y_m:.4f}\n")
                n += 1
    return n
