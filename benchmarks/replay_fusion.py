"""Offline replay of a recorded run through a fresh manager ``Fusion``, scored against the run's ground truth.

A ``panostereo demo`` run directory holds ``recording.mcap`` (every sample on the bus, with its arrival time at
the recorder) and ``gt.csv``. This feeds every recorded Features/SensorInfo sample to a new
:class:`resource_manager.fusion.Fusion` in arrival order, ticking at the instants the live manager ticked (its
recorded TrackSets: fusion instant = TrackSet stamp, samples that arrived before the TrackSet are in the batch;
without TrackSets, ``rate_hz`` ticks at ``latency_ms`` behind the arrival clock), then scores the replayed
tracks like the demo does (``user_agent.report``) and also, for comparison, the live tracks of the recording.

Usage::

    python -m benchmarks.replay_fusion RUN_DIR [RUN_DIR ...] [--manager-config F] [--seconds]

Without ``--manager-config`` the manager config of the recorded site (``deploy/sites/<site>.toml``) is used: a
run whose manager was a variant (e.g. the site accuracy test's) needs its config given.

Prints JSON: per run MOTA, IDF1, ID switches, misses, false positives, mean error, and (``--seconds``) misses /
false positives / switches per second of the run, so one sees *where* frames are lost. The ground truth is read
only to score; nothing of it reaches the Fusion.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from common.config import resolve_path
from common.errors import ConfigError
from common.schema import Features, SensorInfo, TrackSet
from common.site import load_site
from resource_manager.config import ManagerConfig, for_site, load_manager_config
from resource_manager.fusion import Batch, Fusion
from user_agent.groundtruth import GroundTruth, read_gt_csv
from user_agent.messages import decode_on_key
from user_agent.record import keys_for
from user_agent.recording import Recording, iter_raw, read_metadata
from user_agent.report import score_recording

SITES = Path(__file__).resolve().parents[1] / "deploy" / "sites"
"""Where a recording's site (its ``site`` metadata: the site name) is looked up for its manager config."""

__all__ = ["ReplayInput", "load_input", "main", "replay", "score"]


@dataclass
class ReplayInput:
    """The samples of one recording a manager consumes, in arrival order."""

    samples: list[tuple[int, Features | SensorInfo]] = field(default_factory=list)
    """(arrival ns, message)."""
    ticks: list[tuple[int, int]] = field(default_factory=list)
    """(arrival ns of the live TrackSet, its fusion instant ns) of the live manager's ticks."""
    live: list[TrackSet] = field(default_factory=list)
    metadata: dict[str, str] = field(default_factory=dict)


def load_input(recording: Path) -> ReplayInput:
    """Decode the Features, SensorInfo and TrackSet samples of a recording."""
    out = ReplayInput(metadata=read_metadata(recording))
    for s in iter_raw(recording):
        keys = keys_for(s.key)
        if keys is None:
            continue
        msg = decode_on_key(keys, s.key, s.data)
        if isinstance(msg, Features | SensorInfo):
            out.samples.append((s.log_time_ns, msg))
        elif isinstance(msg, TrackSet):
            out.live.append(msg)
            out.ticks.append((s.log_time_ns, msg.stamp_ns))
    out.samples.sort(key=lambda p: p[0])
    out.ticks.sort()
    return out


def replay(data: ReplayInput, config: ManagerConfig) -> tuple[list[TrackSet], list[float]]:
    """Run a fresh Fusion over the recording; returns its TrackSets and each tick's wall time (ms)."""
    fusion = Fusion(config)
    ticks = data.ticks
    if not ticks and data.samples:  # no live manager recorded: tick at rate_hz behind the arrival clock
        period = int(1e9 / config.manager.rate_hz)
        lat = int(config.manager.latency_ms * 1e6)
        t0, t1 = data.samples[0][0], data.samples[-1][0]
        ticks = [(t, t - lat) for t in range(t0 + period, t1 + period, period)]
    out: list[TrackSet] = []
    tick_ms: list[float] = []
    k = 0
    n = len(data.samples)
    for arrival_ns, fusion_ns in ticks:
        feats: list[Features] = []
        infos: list[SensorInfo] = []
        while k < n and data.samples[k][0] <= arrival_ns:
            msg = data.samples[k][1]
            (feats if isinstance(msg, Features) else infos).append(msg)  # type: ignore[arg-type]
            k += 1
        began = time.perf_counter()
        fusion.absorb(Batch(features=feats, infos=infos))
        result = fusion.step(fusion_ns)
        tick_ms.append((time.perf_counter() - began) * 1e3)
        if not result.skipped and result.trackset is not None:
            out.append(result.trackset)
    return out + fusion.flush(), tick_ms


def score(
    tracksets: list[TrackSet], gt: GroundTruth, metadata: dict[str, str], *, threshold_m: float = 0.5
) -> dict[str, Any]:
    """CLEAR-MOT and IDF1 of TrackSets through ``user_agent.report.score_recording``, plus per-second events."""
    rec = Recording(metadata=metadata, tracksets=tracksets)
    fps = rec.meta_float("fps", -1.0)  # score_recording refuses a recording without it before any frame is scored
    per_s: dict[int, list[int]] = {}
    missed: dict[str, dict[int, int]] = {}

    def tally(f: int, events: list[tuple[str, str, str, float]]) -> None:
        second = int((f - 1) / fps)
        sec = per_s.setdefault(second, [0, 0, 0])
        for kind, obj, _hyp, _dist in events:
            if kind == "MISS":
                sec[0] += 1
                who = missed.setdefault(obj, {})
                who[second] = who.get(second, 0) + 1
            elif kind == "FP":
                sec[1] += 1
            elif kind == "SWITCH":
                sec[2] += 1

    m = score_recording(rec, gt, threshold_m=threshold_m, on_events=tally).metrics
    return {
        "mota": round(m.mota, 4),
        "idf1": round(m.idf1, 4),
        "id_switches": m.id_switches,
        "misses": m.misses,
        "false_positives": m.false_positives,
        "objects": m.objects,
        "mean_error_m": round(m.mean_error_m, 4) if math.isfinite(m.mean_error_m) else None,
        "track_ids": m.track_ids,
        "per_second": {str(s): f"miss {v[0]} fp {v[1]} sw {v[2]}" for s, v in sorted(per_s.items()) if any(v)},
        "missed_by_person": {o: " ".join(f"{s}s:{n}" for s, n in sorted(d.items())) for o, d in sorted(missed.items())},
    }


def _manager_config(run_dir: Path, metadata: dict[str, str], given: str | None) -> ManagerConfig:
    name = metadata.get("site", "")
    site_path = Path(name) if name.endswith(".toml") else SITES / f"{name}.toml"
    site = load_site(site_path) if name and site_path.is_file() else None
    if given:
        cfg = load_manager_config(given)
        return for_site(cfg, site) if site is not None else cfg
    if site is not None:
        for proc in site.process:
            if proc.command == "manager":
                return for_site(load_manager_config(resolve_path(site.path, proc.config)), site)
    raise ConfigError(f"{run_dir}: site {name!r} of the recording has no manager in {SITES}: pass --manager-config")


def run_one(run_dir: Path, config_path: str | None, per_second: bool) -> dict[str, Any]:
    """Replay and score one run directory."""
    data = load_input(run_dir / "recording.mcap")
    gt = read_gt_csv(run_dir / "gt.csv")
    config = _manager_config(run_dir, data.metadata, config_path)
    tracksets, tick_ms = replay(data, config)
    rep = score(tracksets, gt, data.metadata)
    live = score(data.live, gt, data.metadata)
    if not per_second:
        for d in (rep, live):
            d.pop("per_second")
            d.pop("missed_by_person")
    return {
        "run": run_dir.name,
        "ticks": len(tracksets),
        "tick_ms_mean": round(float(np.mean(tick_ms)), 3) if tick_ms else None,
        "replay": rep,
        "live": {k: live[k] for k in ("mota", "idf1", "id_switches", "misses", "false_positives")},
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="replay_fusion", description=__doc__.split("\n\n")[0])
    p.add_argument("runs", nargs="+", help="run directories (recording.mcap + gt.csv)")
    p.add_argument("--manager-config", default=None, help="manager TOML (default: the site's manager)")
    p.add_argument("--seconds", action="store_true", help="misses/FPs/switches per second of the run")
    args = p.parse_args(argv)
    results = [run_one(Path(r), args.manager_config, args.seconds) for r in args.runs]
    if len(results) > 1:
        keys = ("mota", "idf1")
        mean = {k: round(float(np.mean([r["replay"][k] for r in results])), 4) for k in keys}
        print(json.dumps({"runs": results, "mean_replay": mean}, indent=1))
    else:
        print(json.dumps(results[0], indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
