"""Run the pure Fusion on synthetic features and score it (shared by tests and benchmarks)."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import msgspec
import numpy as np

from common.schema import Features
from resource_manager.config import ManagerConfig, ManagerSection
from resource_manager.fusion import Batch, Fusion, TickResult
from resource_manager.track.model import TrackModel
from tests.unit.resource_manager.synth import Cam, Person, features_for, info_for, mota

T0_NS = 1_800_000_000_000_000_000


@dataclass
class RunResult:
    mota: dict[str, float]
    errors_m: list[float]
    tick_ms: list[float]
    ids: set[str]
    tick_cpu_ms: list[float] = field(default_factory=list)
    """Thread CPU time per tick (robust to other processes sharing the cores)."""
    results: list[TickResult] = field(default_factory=list)
    gt: list[dict[int, tuple[float, float]]] = field(default_factory=list)
    """Per scored tick: person index -> true position."""
    hyp: list[dict[str, tuple[float, float]]] = field(default_factory=list)
    """Per scored tick: track id -> published position."""

    @property
    def mean_error_m(self) -> float:
        return float(np.mean(self.errors_m)) if self.errors_m else math.inf


def make_config(mid: str = "m1", tracker: dict[str, object] | None = None, **manager: object) -> ManagerConfig:
    """A manager config with these ``[manager]`` (and ``[tracker]``) keys, defaults elsewhere."""
    return ManagerConfig(
        manager=msgspec.convert({"id": mid, **manager}, ManagerSection),
        tracker=msgspec.convert(tracker or {}, TrackModel),
    )


def run_scenario(
    cams: list[Cam],
    people_at: Callable[[float], list[Person]],
    *,
    duration_s: float = 20.0,
    fps: float = 15.0,
    rate_hz: float = 10.0,
    latency_s: float = 0.2,
    seed: int = 1,
    config: ManagerConfig | None = None,
    warmup_s: float = 2.0,
    deliver: Callable[[list[Features], np.random.Generator], list[Features]] | None = None,
    keep_results: bool = False,
    move: Callable[[float, list[Cam], TickResult], None] | None = None,
) -> RunResult:
    """Feed frames as they would arrive (capture time <= now), tick at ``rate_hz`` fusing at now - latency.

    ``deliver`` may reorder/duplicate/drop each tick's batch; ``move`` may move cameras after each tick
    (closed-loop view planning).
    """
    rng = np.random.default_rng(seed)
    fusion = Fusion(config or make_config())
    frame_dt = 1.0 / fps
    next_frame = 0
    seq = 0
    gt: list[dict[int, tuple[float, float]]] = []
    hyp: list[dict[str, tuple[float, float]]] = []
    errors: list[float] = []
    tick_ms: list[float] = []
    cpu_ms: list[float] = []
    ids: set[str] = set()
    results: list[TickResult] = []
    infos_sent = False
    for tick in range(int(duration_s * rate_hz)):
        now = tick / rate_hz
        batch: list[Features] = []
        while next_frame * frame_dt <= now:
            t = next_frame * frame_dt
            ps = people_at(t)
            batch += [features_for(c, ps, cams, T0_NS + int(t * 1e9), seq, rng) for c in cams]
            next_frame += 1
            seq += 1
        if deliver is not None:
            batch = deliver(batch, rng)
        infos = [info_for(c) for c in cams] if not infos_sent else []
        infos_sent = True
        t_fuse = now - latency_s
        if t_fuse <= 0:
            fusion.absorb(Batch(features=batch, infos=infos))
            continue
        start = time.perf_counter()
        cpu0 = time.thread_time()
        fusion.absorb(Batch(features=batch, infos=infos))
        res = fusion.step(T0_NS + int(t_fuse * 1e9))
        cpu_ms.append((time.thread_time() - cpu0) * 1e3)
        tick_ms.append((time.perf_counter() - start) * 1e3)
        if keep_results:
            results.append(res)
        if move is not None:
            move(now, cams, res)
        if t_fuse < warmup_s:
            continue
        truth = people_at(t_fuse)
        g = {k: (p.x, p.y) for k, p in enumerate(truth)}
        h = {tr.track_id: (tr.x_m, tr.y_m) for tr in res.trackset.tracks}
        gt.append(g)
        hyp.append(h)
        ids.update(h)
        for x, y in h.values():
            errors.append(min(math.hypot(x - p.x, y - p.y) for p in truth) if truth else math.inf)
    return RunResult(mota(gt, hyp), errors, tick_ms, ids, tick_cpu_ms=cpu_ms, results=results, gt=gt, hyp=hyp)
