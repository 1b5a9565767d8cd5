"""Score and plot a recording: the shared back end of ``evaluate``, ``plot`` and ``demo``."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from common.errors import ConfigError
from user_agent.evaluate import MotMetrics, evaluate_positions, hypotheses_from_tracksets, unseen_spans
from user_agent.groundtruth import GroundTruth, read_gt_csv
from user_agent.plot import PlotInput, save_top_view
from user_agent.recording import Recording, load_recording

__all__ = ["Scored", "plot_recording", "room_of", "score_recording"]


@dataclass(frozen=True, slots=True)
class Scored:
    metrics: MotMetrics
    tracks_published: int
    """Distinct confirmed/coasting track ids in the recording."""
    tracksets: int
    frames_scored: int
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
) -> Scored:
    """Evaluate a recording's TrackSets against ground truth.

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
    unseen = unseen_spans(rec.tracksets, max_gap_s)
    hyps, frames = hypotheses_from_tracksets(
        rec.tracksets,
        epoch,
        rate,
        gt.frame_numbers,
        max_gap_s=max_gap_s,
        start_ns=start if start >= 0 else None,
        skip=unseen,
    )
    metrics = evaluate_positions(gt, hyps, threshold_m, frames=frames, on_events=on_events)
    published = {t.track_id for ts in rec.tracksets for t in ts.tracks if t.state in ("confirmed", "coasting")}
    unseen_s = sum(b - a for a, b in unseen) / 1e9
    return Scored(metrics, len(published), len(rec.tracksets), len(frames), unseen_s)


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


def plot_recording(
    rec: Recording | str | Path,
    out: str | Path,
    ground_truth: GroundTruth | str | Path | None = None,
    title: str = "",
    gt_cameras: dict[str, list[tuple[float, float]]] | None = None,
) -> Path:
    """Write the top-view PNG of a recording (ground truth beside it when given)."""
    r = rec if isinstance(rec, Recording) else load_recording(rec)
    gt = read_gt_csv(ground_truth) if isinstance(ground_truth, str | Path) else ground_truth
    if gt is not None and r.tracksets:
        # Only the recorded span of the ground truth, so both panels show the same time window.
        epoch, fps = r.meta_int("epoch_ns", -1), r.meta_float("fps", -1.0)
        if epoch >= 0 and fps > 0:
            t0 = (r.tracksets[0].stamp_ns - epoch) / 1e9
            t1 = (r.tracksets[-1].stamp_ns - epoch) / 1e9
            keep = {k: v for k, v in gt.frames.items() if t0 - 0.5 <= (k - 1) / fps <= t1 + 0.5}
            gt = GroundTruth(keep, gt.source)
    inp = PlotInput(
        tracksets=r.tracksets,
        sensor_infos=list(r.sensor_infos.values()),
        pairs=r.pairs,
        ground_truth=gt,
        room_m=room_of(r),
        title=title,
        gt_cameras=gt_cameras,
        mutual_paths=r.mutual_paths,
    )
    return save_top_view(inp, out)
