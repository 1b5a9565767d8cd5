"""Dataset time: a dataset site played through the manager's own stages, with no wall clock and no zenoh.

A dataset site (``panostereo import mot|wildtrack``) has detection-file sensor nodes and a manager. Played
live (``panostereo demo --site``), every node turns frame ``k`` of its file into Features at world time
``(k - 1) / fps`` and the manager fuses them over zenoh. Here the same code runs in one process, in dataset
time:

1. each node's config is built with :func:`sensor_node.build.build_node` and its frames turned into Features
   by the node's own processor (the same 2D tracker, the same rays), and its SensorInfo by the same function the
   node publishes;
2. the manager's :class:`~resource_manager.fusion.Fusion` (the site's manager config, or another) is fed every
   frame at its own stamp and fuses the instants the live manager's watermark rule allows
   (:mod:`resource_manager.ingest.schedule`): every frame instant, once each camera's frame of it is in;
3. the TrackSets are scored against the site's ``gt.csv`` from its first frame
   (:func:`user_agent.report.score_tracksets`), where the ground truth annotates people
   (``[dataset] scored_area``), and everywhere as well.

Nothing is random and nothing waits: two runs give identical tracks, and Wildtrack's 400 frames take seconds.
Ground truth is read only by the scoring, after the tracks are made.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import msgspec
import numpy as np

from common.area import Area
from common.arrays import FloatArray
from common.errors import ConfigError
from common.frames import Frame
from common.schema import Features, SensorInfo, TrackSet
from common.site import SiteConfig, load_site
from resource_manager.config import MAX_PUBLISH_LAG_S, ManagerConfig, for_site, load_manager_config
from resource_manager.fusion import Batch, Fusion, TickResult
from resource_manager.poses.agreement import Agreement
from sensor_node.build import DetectionProcessor, build_node, sensor_info
from sensor_node.config import DetectionsSource, load_node_config
from sensor_node.detections import DetectionFrames
from user_agent.evaluate import HypPoint
from user_agent.groundtruth import GroundTruth, read_gt_csv, speed_warning
from user_agent.report import Scored, score_tracksets

__all__ = ["DATASET_EPOCH_NS", "DatasetCamera", "DatasetRun", "evaluate_site", "load_cameras", "play", "plot_site",
           "scored_first", "site_manager_config"]  # fmt: skip

DATASET_EPOCH_NS = 1_700_000_000_000_000_000
"""World time 0 of a dataset played in dataset time (any fixed instant: the result does not depend on it)."""


@dataclass(frozen=True, slots=True)
class DatasetCamera:
    """One detection-file node of a site, its frames already turned into Features."""

    sensor_id: str
    info: SensorInfo
    features: list[Features]
    """One per frame of the file, stamped at the frame's world time."""


@dataclass(slots=True)
class DatasetRun:
    """What one play produced."""

    tracksets: list[TrackSet] = field(default_factory=list)
    ticks: int = 0
    tick_ms: list[float] = field(default_factory=list)
    """Process time of each Fusion step (ms)."""
    infos: list[SensorInfo] = field(default_factory=list)
    """What each camera is (its SensorInfo), for the picture."""
    hypotheses: dict[int, list[HypPoint]] = field(default_factory=dict)
    """The tracks at every scored ground-truth frame (set by :func:`evaluate_site`)."""
    shared_recall: dict[str, float] = field(default_factory=dict)
    """The recall the manager learnt of each multi-view detector the cameras name (``shared_detector``), at the end."""


def load_cameras(site: SiteConfig, epoch_ns: int = DATASET_EPOCH_NS) -> list[DatasetCamera]:
    """Every sensor node of a dataset site, read and turned into Features by the node's own code.

    Raises:
        ConfigError: a node whose source is not a detection file (dataset time plays recorded detections).
    """
    out: list[DatasetCamera] = []
    for proc in site.process:
        if proc.command != "node":
            continue
        cfg = load_node_config(site.resolve(proc.config))
        if not isinstance(cfg.source, DetectionsSource):
            kind = type(cfg.source).__name__
            raise ConfigError(
                f"{site.path}: process {proc.name!r} has a {kind} source; dataset time plays detection-file "
                f'nodes ([source] kind = "detections") only: run this site live with `panostereo demo --site`'
            )
        cfg = _with_epoch(cfg, epoch_ns)
        parts = build_node(cfg, lambda: epoch_ns)
        frames = parts.source
        assert isinstance(frames, DetectionFrames)
        last = site.dataset.frames if site.dataset is not None and site.dataset.frames else frames.last_frame
        period_ns = 1e9 / cfg.source.fps
        processor = parts.processor
        assert isinstance(processor, DetectionProcessor)
        played = [
            Frame(index=k - 1, stamp_ns=epoch_ns + round((k - 1) * period_ns), payload=frames.by_frame.get(k, []))
            for k in range(1, last + 1)
        ]
        feats = processor.process_frames(played, first_seq=1)
        info = sensor_info(cfg, parts, seq=0, stamp_ns=epoch_ns)
        out.append(DatasetCamera(cfg.node.id, info, feats))
    if not out:
        raise ConfigError(f'{site.path}: no sensor node ([[process]] command = "node") to play')
    return out


def _with_epoch(cfg: Any, epoch_ns: int) -> Any:
    return msgspec.structs.replace(cfg, source=msgspec.structs.replace(cfg.source, epoch_ns=epoch_ns))


def play(
    cameras: Sequence[DatasetCamera],
    config: ManagerConfig,
    on_tick: Callable[[int, TickResult], None] | None = None,
    infos_at: Sequence[tuple[int, SensorInfo]] = (),
) -> DatasetRun:
    """Feed a fresh Fusion every frame as it would arrive (at its own stamp) and fuse the instants the live
    manager's watermark rule allows (:mod:`resource_manager.ingest.schedule`): here, every frame instant.

    ``on_tick``: called with each fused instant and its whole result (for what reads more than the TrackSets, as
    the live manager's cameras' agreement check does). ``infos_at``: (stamp, SensorInfo) given to the manager just
    before the first frame at or after that stamp (a camera's calibration changed while it ran)."""
    fusion = Fusion(config)
    by_stamp: dict[int, list[Features]] = {}
    for cam in cameras:
        for f in cam.features:
            by_stamp.setdefault(f.stamp_ns, []).append(f)
    run = DatasetRun()

    def fuse_at(now_ns: int) -> None:
        t_ns = fusion.next_instant(now_ns)
        if t_ns is None:
            return
        began = time.process_time()
        result = fusion.step(t_ns)
        run.tick_ms.append((time.process_time() - began) * 1e3)
        run.ticks += 1
        if not result.skipped and on_tick is not None:
            on_tick(t_ns, result)
        if not result.skipped and result.trackset is not None:
            run.tracksets.append(result.trackset)

    fusion.absorb(Batch(infos=[cam.info for cam in cameras], presence={cam.sensor_id: True for cam in cameras}))
    now_ns = 0
    pending = list(infos_at)
    for stamp in sorted(by_stamp):
        # Between frames, wake at the deadlines the live manager sleeps until (a camera with no frame at an
        # instant stops being waited for there, as it would live).
        while now_ns and (due := fusion.until_due_ns(now_ns)) is not None and now_ns + due < stamp:
            now_ns += max(due, 1)
            fuse_at(now_ns)
        now_ns = stamp
        changed = [info for at, info in pending if at <= stamp]
        pending = [(at, info) for at, info in pending if at > stamp]
        fusion.absorb(Batch(infos=changed, features=by_stamp[stamp]))
        fuse_at(stamp)
    run.tracksets += fusion.flush()  # what publish_lag_s still holds at the end of the dataset
    run.shared_recall = fusion.tracker.recall.learnt()
    return run


@dataclass
class AgreementTally:
    """The live manager's check that each camera agrees with the others (:mod:`resource_manager.poses.agreement`,
    ``ManagerStatus.agreement``) over a played run: per camera, at how many instants it disagreed and its residual
    then, from the check's first full window on. ``bucket``: which tally an instant counts in (None: none)."""

    bucket: Callable[[int], str | None] = lambda t_ns: "run"
    check: Agreement = field(default_factory=Agreement)
    first_ns: int | None = None
    checked: dict[str, dict[str, list[tuple[bool, float]]]] = field(default_factory=dict)
    """bucket -> sensor id -> (whether it disagreed, its residual in m) at each instant checked."""

    def on_tick(self, t_ns: int, result: TickResult) -> None:
        self.check.update(t_ns, result.views, result.people)
        self.first_ns = t_ns if self.first_ns is None else self.first_ns
        name = self.bucket(t_ns)
        if t_ns - self.first_ns < self.check.params.window_s * 1e9 or name is None:
            return
        for a in self.check.report():
            self.checked.setdefault(name, {}).setdefault(a.sensor_id, []).append((a.disagrees, a.residual_m))

    def shares(self, name: str = "run") -> dict[str, float]:
        """Per camera, the share of the instants checked at which it disagreed."""
        got = self.checked.get(name, {})
        return {sid: round(sum(d for d, _ in got[sid]) / len(got[sid]), 3) for sid in sorted(got)}

    def summary(self, name: str = "run") -> list[dict[str, Any]]:
        """Per camera, the most often disagreeing first: ``disagreed_share`` and the median ``residual_m``."""
        got = self.checked.get(name, {})
        rows = [
            {
                "sensor_id": sid,
                "disagreed_share": share,
                "residual_m": round(float(np.median([r for _, r in got[sid]])), 3),
            }
            for sid, share in self.shares(name).items()
        ]
        return sorted(rows, key=lambda r: (-r["disagreed_share"], -r["residual_m"]))


def site_manager_config(site: SiteConfig, given: str | Path | None) -> ManagerConfig:
    """The site's manager config (or ``given``) as the manager of this site: its sensors, its area."""
    if given:
        return for_site(load_manager_config(given), site)
    for proc in site.process:
        if proc.command == "manager":
            return for_site(load_manager_config(site.resolve(proc.config)), site)
    raise ConfigError(f"{site.path}: no manager process: pass --config MANAGER.toml")


def evaluate_site(
    site_path: str | Path,
    *,
    manager_config: str | Path | None = None,
    thresholds_m: Sequence[float] = (0.5, 1.0),
    publish_lag_s: float | None = None,
) -> tuple[dict[str, Any], DatasetRun]:
    """Play a dataset site in dataset time and score it at each threshold.

    ``publish_lag_s`` (default: the manager config's): with a lag, the tracks published that late are scored, and
    the live ones (no lag) beside them, under ``live``. ``agreement``: how often each camera's blobs disagreed
    with where the others put the people (:class:`AgreementTally`): a camera off its calibration.

    Returns:
        (a JSON-ready report, the run).

    Raises:
        ConfigError: not a dataset site, no ground truth, a node that is not a detection file, a bad config.
    """
    site = load_site(site_path)
    if site.dataset is None:
        raise ConfigError(f"{site.path}: not a dataset site (no [dataset] table): evaluate-site plays recorded data")
    if not site.dataset.ground_truth:
        raise ConfigError(f"{site.path}: the dataset has no ground truth (dataset.ground_truth) to score against")
    gt_path = site.resolve(site.dataset.ground_truth)
    if not gt_path.is_file():
        raise ConfigError(f"{site.path}: dataset.ground_truth {site.dataset.ground_truth!r} not found ({gt_path})")
    config = site_manager_config(site, manager_config)
    if publish_lag_s is not None:
        if not (math.isfinite(publish_lag_s) and 0.0 <= publish_lag_s <= MAX_PUBLISH_LAG_S):
            raise ConfigError(f"--publish-lag-s must be in [0, {MAX_PUBLISH_LAG_S:g}] s, got {publish_lag_s}")
        config = msgspec.structs.replace(
            config, manager=msgspec.structs.replace(config.manager, publish_lag_s=publish_lag_s)
        )
    began = time.perf_counter()
    cameras = load_cameras(site)
    loaded = time.perf_counter()
    tally = AgreementTally()
    run = play(cameras, config, on_tick=tally.on_tick)
    run.infos = [c.info for c in cameras]
    played = time.perf_counter()
    gt = read_gt_csv(gt_path)
    report = _report(site, run, gt, thresholds_m)
    report.update(
        {
            "cameras": [c.sensor_id for c in cameras],
            "frames": max((len(c.features) for c in cameras), default=0),
            "publish_lag_s": config.manager.publish_lag_s,
            "seconds": {"load": round(loaded - began, 3), "play": round(played - loaded, 3)},
            "tick_ms_mean": round(sum(run.tick_ms) / len(run.tick_ms), 3) if run.tick_ms else None,
            "shared_detector_recall": {name: round(r, 4) for name, r in run.shared_recall.items()},
            "agreement": tally.summary(),
        }
    )
    if config.manager.publish_lag_s > 0:
        live = play(
            cameras, msgspec.structs.replace(config, manager=msgspec.structs.replace(config.manager, publish_lag_s=0.0))
        )
        report["live"] = {k: v for k, v in _report(site, live, gt, thresholds_m).items() if k.startswith("scores")}
    return report, run


ENDED_BEFORE_S = 1.0
"""A track last published this long before the last TrackSet ended during the run (not just at its end)."""


def ended_inside(tracksets: Sequence[TrackSet], area: Area | None) -> int | None:
    """How many published tracks ended during the run inside the area, a stride (``ENDED_BEFORE_S`` of walking at
    1 m/s) or more from any exit: people who cannot have left, whose track ended anyway. None without an area."""
    if area is None or not tracksets:
        return None
    last: dict[str, tuple[int, float, float]] = {}
    for ts in tracksets:
        for t in ts.tracks:
            last[t.track_id] = (ts.stamp_ns, t.x_m, t.y_m)
    end_ns = max(ts.stamp_ns for ts in tracksets)
    gone = [(x, y) for stamp, x, y in last.values() if stamp < end_ns - ENDED_BEFORE_S * 1e9]
    if not gone:
        return 0
    xy = np.array(gone)
    return int(np.sum(area.contains(xy) & (area.exit_distance(xy) > ENDED_BEFORE_S * 1.0)))


def scored_first(site: SiteConfig, gt: GroundTruth) -> tuple[FloatArray | None, FloatArray | None]:
    """(where a dataset site's tracks are scored first, the ground truth's hull), each None for everywhere.

    A site that declares its area says where people are: every track counts, first. Without one, the ground truth's
    hull (``[dataset] scored_area = "ground_truth"``) is where anyone can say whether someone is there."""
    assert site.dataset is not None
    hull = gt.area() if site.dataset.scored_area == "ground_truth" else None
    return (None if site.area is not None else hull), hull


def _report(site: SiteConfig, run: DatasetRun, gt: GroundTruth, thresholds_m: Sequence[float]) -> dict[str, Any]:
    """The scores of a run (and its tracks at the ground truth's frames, into ``run.hypotheses``)."""
    assert site.dataset is not None
    primary, hull = scored_first(site, gt)
    fps = site.dataset.fps

    def score(t: float, where: FloatArray | None) -> Scored:
        return score_tracksets(run.tracksets, gt, epoch_ns=DATASET_EPOCH_NS, fps=fps, threshold_m=t, area=where)

    scored = [score(t, primary) for t in thresholds_m]
    run.hypotheses = scored[0].hypotheses if scored else {}
    report: dict[str, Any] = {
        "site": site.site.name,
        "fps": site.dataset.fps,
        "scored_area": "ground_truth" if primary is not None else "everywhere",
        "scores": [s.metrics.to_dict() for s in scored],
        "tracks_published": len({t.track_id for ts in run.tracksets for t in ts.tracks}),
        "tracks_ended_inside": ended_inside(run.tracksets, Area.of(site.area) if site.area is not None else None),
    }
    warning = speed_warning(gt, fps)
    if warning:
        report["warnings"] = [warning]
    if primary is not None:
        # The same tracks scored everywhere too: those outside the annotated area count as false positives.
        report["scores_everywhere"] = [score(t, None).metrics.to_dict() for t in thresholds_m]
    else:
        report["scores_everywhere"] = report["scores"]
        if hull is not None:
            report["scores_annotated"] = [score(t, hull).metrics.to_dict() for t in thresholds_m]
    return report


def plot_site(site_path: str | Path, run: DatasetRun, out: str | Path, *, threshold_m: float = 0.5) -> Path:
    """Draw a played dataset site: its tracks beside the ground truth, and the timeline of who was followed by
    which track (scored where the ground truth annotates people, as :func:`evaluate_site` does)."""
    from user_agent.plot import PlotInput, save_top_view

    site = load_site(site_path)
    if site.dataset is None:
        raise ConfigError(f"{site.path}: not a dataset site (no [dataset] table)")
    gt = read_gt_csv(site.resolve(site.dataset.ground_truth))
    inp = PlotInput(
        tracksets=run.tracksets,
        sensor_infos=run.infos,
        pairs=[],
        ground_truth=gt,
        area=[(float(x), float(y)) for x, y in site.area.polygon] if site.area is not None else None,
        title=f"{site.site.name} (dataset time)",
        epoch_ns=DATASET_EPOCH_NS,
        fps=site.dataset.fps,
        threshold_m=threshold_m,
        scored_area=scored_first(site, gt)[0],
    )
    return save_top_view(inp, out)
