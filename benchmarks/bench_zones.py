"""Zones benchmark (issue 25, item 6): one manager for a whole hall against four zone managers, and failover.

Usage::

    python -m benchmarks.bench_zones [--sensors 64] [--fps 30] [--people 60] [--duration 60] [--kills 5] [--out FILE]
    python -m benchmarks.bench_zones --quick       # a smoke run: 8 cameras, 8 people, 8 s, 2 kills

The site is the feature-level version of ``deploy/sites/hall.toml``: a 40 x 20 m hall cut into four 20 x 10 m
zones, ``--sensors`` panoramic cameras in a grid (the same number in each zone), ``--people`` people walking
between random points of the whole hall (so across the borders). A *fleet* process (``bench_load``'s: no pixels,
one Features message per camera and frame) plays them; each camera sees people within ``--range-m``; a zone
manager fuses the cameras inside its zone or within ``--zone-reach-m`` of it (``[[zones]] reach_m``). Everything
is real processes on loopback: a ``panostereo router`` (multicast scouting off), ``panostereo manager --site F``
processes (``--zone Z`` for a zone manager), the fleet, and this process as the user agent (subscribed to
``R/tracks`` and the managers' status).

Three runs, one after the other, with the same seed (same people, same cameras):

* ``single``: one manager fuses every camera;
* ``zones``: four zone managers;
* ``failover``: the four zone managers and a standby for zone ``nw``; the zone's leader is SIGKILLed ``--kills``
  times at seeded random instants (after the standby is warm), and restarted each time (it joins as standby).

Figures (one JSON object on stdout, and in ``--out``):

* per run: site-wide MOTA and IDF1 (``user_agent.evaluate`` against the fleet's ground truth, every manager's
  tracks together, match distance 0.5 m, scored at 10 Hz after ``--warmup``), each manager's median fusion tick,
  wall clock and the fusing thread's CPU time (``ManagerStatus.tick_ms``, ``tick_cpu_ms``), CPU use, and where
  its capture -> publish time went (``ManagerStatus.latency``: node, transport, wait, fusion, publish), capture ->
  agent latency p50/p99, frames lost (the fleet's frames of a manager's cameras it did not receive),
  the share of person-instants published by more than one manager (a person matched to one manager's track with
  another manager's track, matched to nobody, beside them), and the border crossings that kept their track id
  (the person's matched track just before and just after);
* ``zone_vs_single``: the differences in MOTA and IDF1, and the zone managers' tick time over the single one's,
  wall clock and CPU (five managers on a two-core host wait for a core: their wall ticks hold that wait, their
  CPU ticks only the fusion's own work, what a host of their own would take);
* ``failover``: per kill, the time from the kill to the new leader's first TrackSet, the share of the old leader's
  ids published in the second after it (by the new leader, or by a neighbour for a person who walked on into its
  zone meanwhile), the ids lost, and whether the other zones' managers were disturbed (a gap in their TrackSets);
* ``fleet``: whether one fleet process kept up with ``--sensors`` x ``--fps`` on this machine (its worst lateness
  against the frame schedule, and the frames it sent per second);
* ``hosts_estimate``: a linear cost model fitted to the managers' measured CPU (per camera-frame fused and per
  tracked person-tick) and the router's (per frame delivered), applied to a 1,000-camera, 1,000-person site.
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import os
import random
import re
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy.optimize import linear_sum_assignment

from benchmarks.bench_load import (
    REPO,
    Cam,
    Walker,
    _free_port,
    _percentiles,
    _wait_port,
    make_room,
    run_fleet,
    stop_processes,
)
from common.codec import decode
from common.keys import Keys
from common.schema import ManagerStatus, TrackSet
from common.session import SessionSettings, open_session
from user_agent.evaluate import HypPoint, evaluate_positions, hypotheses_from_tracksets
from user_agent.groundtruth import GroundTruth, GtPoint

HALL_X_M, HALL_Y_M = 40.0, 20.0
ZONES = {"sw": (0.0, 20.0, 0.0, 10.0), "se": (20.0, 40.0, 0.0, 10.0), "nw": (0.0, 20.0, 10.0, 20.0)}
ZONES["ne"] = (20.0, 40.0, 10.0, 20.0)
FAILOVER_ZONE = "nw"
GT_HZ = 10.0
"""Ground-truth frames per second the tracks are scored at."""
THRESHOLD_M = 0.5
CROSSING_WINDOW_S = 2.0
"""A crossing is judged by the person's matched track within this long before and after it."""
PREFIX = "zones"
ESTIMATE_SITE = {"cameras": 1000, "people": 1000, "fps": 30.0}
"""The site the host estimate is for (the issue's: 1,000 cameras at 30 Hz, 1,000 people)."""
QUICK = {"sensors": 8, "people": 8, "duration": 8.0, "kills": 2, "warmup": 3.0}
"""``--quick``: a smoke run's sizes."""
CLK_TCK = os.sysconf("SC_CLK_TCK")


# ---------------------------------------------------------------------------
# The hall: cameras in a grid, people on random beats across it
# ---------------------------------------------------------------------------


def make_hall(sensors: int, people: int, seed: int) -> tuple[list[Cam], list[Walker]]:
    """``sensors`` cameras, as evenly as a grid allows in each zone; ``people`` walking between random points."""
    per_zone = [sensors // 4 + (1 if i < sensors % 4 else 0) for i in range(4)]
    rng = random.Random(seed)
    cams = []
    for (x0, x1, y0, y1), k in zip(ZONES.values(), per_zone, strict=True):
        cols = max(1, math.ceil(math.sqrt(2 * k)))
        rows = max(1, math.ceil(k / cols))
        for i in range(k):
            c, r = i % cols, i // cols
            x = x0 + (c + 0.5) * (x1 - x0) / cols
            y = y0 + (r + 0.5) * (y1 - y0) / rows
            cams.append(Cam(f"c{len(cams):03d}", x, y, 1.1 + 0.1 * (i % 3), rng.uniform(-math.pi, math.pi)))
    _, room_walkers = make_room(0, people, seed, room_m=HALL_X_M)  # looks, heights, speeds and phases
    rng = random.Random(f"hall-{seed}")
    walkers = [
        Walker(
            w.person_id,
            rng.uniform(1.0, HALL_X_M - 1.0),
            rng.uniform(1.0, HALL_Y_M - 1.0),
            rng.uniform(1.0, HALL_X_M - 1.0),
            rng.uniform(1.0, HALL_Y_M - 1.0),
            w.speed_mps,
            w.height_m,
            w.phase_s,
            w.hist,
        )
        for w in room_walkers
    ]
    return cams, walkers


def zone_of(x: float, y: float) -> str:
    """The zone a floor point is in (a point on a border: the first zone listing it)."""
    for name, (x0, x1, y0, y1) in ZONES.items():
        if x0 <= x <= x1 and y0 <= y <= y1:
            return name
    return ""


def write_site(tmp: Path, endpoint: str, cams: list[Cam], reach_m: float) -> Path:
    """The hall as a site file (its cameras as node processes, its zones), for ``panostereo manager --site``."""
    text = f'[site]\nname = "hall"\nprefix = "{PREFIX}"\nrouter = "{endpoint}"\n'
    text += f"[area]\npolygon = [[0.0, 0.0], [{HALL_X_M}, 0.0], [{HALL_X_M}, {HALL_Y_M}], [0.0, {HALL_Y_M}]]\n"
    for name, (x0, x1, y0, y1) in ZONES.items():
        text += f'[[zones]]\nname = "{name}"\npolygon = [[{x0}, {y0}], [{x1}, {y0}], [{x1}, {y1}], [{x0}, {y1}]]\n'
        text += f"reach_m = {reach_m}\n"
    (tmp / "nodes").mkdir(parents=True, exist_ok=True)
    for cam in cams:
        (tmp / "nodes" / f"{cam.sensor_id}.toml").write_text(f'[node]\nid = "{cam.sensor_id}"\n')
        text += f'[[camera]]\nid = "{cam.sensor_id}"\nx_m = {cam.x_m}\ny_m = {cam.y_m}\n'
        text += f'[[process]]\nname = "{cam.sensor_id}"\ncommand = "node"\nconfig = "nodes/{cam.sensor_id}.toml"\n'
    path = tmp / "site.toml"
    path.write_text(text)
    return path


def manager_config(tmp: Path, mid: str, endpoint: str, rate_hz: float, zone: str) -> Path:
    path = tmp / f"{mid}.toml"
    path.write_text(
        f'[manager]\nid = "{mid}"\nprefix = "{PREFIX}"\nrate_hz = {rate_hz}\nzone = "{zone}"\n'
        f'state_dir = "{tmp / "state" / mid}"\n'
        f'[zenoh]\nmode = "client"\nconnect = ["{endpoint}"]\nconnect_timeout_ms = 20000\nlease_ms = 2000\n'
    )
    return path


def cpu_s(pid: int) -> float | None:
    """User + system CPU seconds of a process so far (None: it is gone)."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return None
    return (int(fields[11]) + int(fields[12])) / CLK_TCK


# ---------------------------------------------------------------------------
# One run: router, managers, fleet, and this process as the agent
# ---------------------------------------------------------------------------


@dataclass
class Run:
    """A live site on loopback and what the agent saw of it."""

    args: argparse.Namespace
    name: str
    tmp: Path = field(default_factory=lambda: Path(tempfile.mkdtemp(prefix="bench-zones-")))
    port: int = field(default_factory=_free_port)
    procs: dict[str, subprocess.Popen[bytes]] = field(default_factory=dict)
    sets: list[tuple[int, TrackSet]] = field(default_factory=list)
    statuses: list[tuple[int, ManagerStatus]] = field(default_factory=list)
    cpu: dict[str, list[tuple[float, float, int]]] = field(default_factory=dict)
    restarted: set[str] = field(default_factory=set)
    """Managers killed and started again (their counters start over: no frames-lost or CPU figure)."""
    lock: threading.Lock = field(default_factory=threading.Lock)
    epoch_ns: int = 0
    span_s: float = 0.0
    """From the fleet's start to its end."""
    site: Path = Path()

    @property
    def endpoint(self) -> str:
        return f"tcp/127.0.0.1:{self.port}"

    def start(self, name: str, argv: list[str]) -> subprocess.Popen[bytes]:
        env = dict(os.environ, PYTHONUNBUFFERED="1", PYTHONPATH=str(REPO))
        with (self.tmp / f"{name}.log").open("ab") as log:
            p = subprocess.Popen(argv, stdout=log, stderr=subprocess.STDOUT, env=env, cwd=REPO)
        self.procs[name] = p
        return p

    def start_manager(self, mid: str, zone: str) -> subprocess.Popen[bytes]:
        cfg = manager_config(self.tmp, mid, self.endpoint, self.args.rate_hz, zone)
        argv = [sys.executable, "-m", "panostereo", "manager", "--config", str(cfg), "--site", str(self.site)]
        return self.start(mid, [*argv, "--log-level", "INFO"] if zone else argv)

    def on_tracks(self, sample: Any) -> None:
        now = time.time_ns()
        ts = decode(sample.payload.to_bytes(), TrackSet)
        with self.lock:
            self.sets.append((now, ts))

    def on_status(self, sample: Any) -> None:
        now = time.time_ns()
        st = decode(sample.payload.to_bytes(), ManagerStatus)
        with self.lock:
            self.statuses.append((now, st))

    def status(self, mid: str, since_ns: int = 0) -> ManagerStatus | None:
        with self.lock:
            got = [st for a, st in self.statuses if st.manager_id == mid and a >= since_ns]
        return got[-1] if got else None

    def sets_of(self, mid: str, since_ns: int = 0) -> list[tuple[int, TrackSet]]:
        with self.lock:
            return [(a, ts) for a, ts in self.sets if ts.manager_id == mid and a >= since_ns]

    def wait(self, pred: Callable[[], Any], timeout_s: float, what: str) -> Any:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            got = pred()
            if got:
                return got
            dead = [n for n, p in self.procs.items() if p.poll() not in (None, -signal.SIGKILL) and n != "fleet"]
            if dead:
                raise SystemExit(f"bench_zones: {dead} exited while waiting for {what} (logs: {self.tmp})")
            time.sleep(0.05)
        raise SystemExit(f"bench_zones: no {what} within {timeout_s} s (logs: {self.tmp})")

    def sample_cpu(self) -> None:
        for name, p in self.procs.items():
            c = cpu_s(p.pid)
            if c is not None:
                self.cpu.setdefault(name, []).append((time.monotonic(), c, p.pid))

    def stop(self) -> None:
        stop_processes(list(self.procs.values()))


def fleet_argv(run: Run, duration_s: float) -> list[str]:
    a = run.args
    return [
        sys.executable,
        "-m",
        "benchmarks.bench_zones",
        "fleet",
        *("--connect", run.endpoint, "--sensors", str(a.sensors), "--fps", str(a.fps)),
        *("--people", str(a.people), "--duration", str(duration_s), "--seed", str(a.seed)),
        *("--range-m", str(a.range_m), "--stats", str(run.tmp / "fleet.json"), "--epoch-ns", str(run.epoch_ns)),
    ]


def start_site(run: Run, managers: dict[str, str], duration_s: float) -> subprocess.Popen[bytes]:
    """Start the managers, then the fleet; a standby (an id ending in ``-b``) once its zone's leader leads (a
    manager claims its zone only when its cameras' frames reach it)."""
    first = [m for m in managers if not m.endswith("-b")]
    for mid in first:
        run.start_manager(mid, managers[mid])
    run.wait(lambda: all(run.status(m) for m in first), 60.0, "status of every manager")
    run.epoch_ns = time.time_ns()
    fleet = run.start("fleet", fleet_argv(run, duration_s))
    for mid in managers.keys() - first:
        lead = f"{mid[:-2]}-a"
        run.wait(lambda m=lead: getattr(run.status(m), "role", "") == "leader", 60.0, f"{lead} leading")
        run.start_manager(mid, managers[mid])
    return fleet


def run_site(args: argparse.Namespace, name: str, managers: dict[str, str], kills: int = 0) -> dict[str, Any]:
    """Run the hall with ``managers`` (id -> zone, "" for none) and score what the agent saw."""
    run = Run(args, name)
    cams, walkers = make_hall(args.sensors, args.people, args.seed)
    run.site = write_site(run.tmp, run.endpoint, cams, args.zone_reach_m)
    keys = Keys(PREFIX)
    kill_log: list[dict[str, Any]] = []
    try:
        run.start("router", [sys.executable, "-m", "panostereo", "router", "--listen", run.endpoint])
        _wait_port(run.port, 20.0)
        with open_session(SessionSettings(mode="client", connect=[run.endpoint])) as s:
            subs = [
                s.declare_subscriber(keys.tracks(), run.on_tracks),
                s.declare_subscriber(keys.all_manager_status, run.on_status),
            ]
            fleet = start_site(run, managers, 0.0 if kills else args.duration)
            t0 = time.monotonic()
            if kills:
                kill_log = failover(run, kills)
            while fleet.poll() is None and time.monotonic() < t0 + args.duration + 60:
                run.sample_cpu()
                if kills:
                    break
                time.sleep(1.0)
            run.sample_cpu()
            if fleet.poll() is None:
                fleet.send_signal(signal.SIGTERM)
            fleet.wait(timeout=60)
            run.span_s = (time.time_ns() - run.epoch_ns) / 1e9
            time.sleep(1.5)  # the last ticks, and a status after the cameras stopped
            for sub in subs:
                sub.undeclare()
    finally:
        run.stop()
    out = score_run(run, cams, walkers, managers)
    if kill_log:
        out["kills"] = kill_log
    return out


# ---------------------------------------------------------------------------
# Failover: the zone's leader SIGKILLed at random instants
# ---------------------------------------------------------------------------


def _confirmed(ts: TrackSet) -> set[str]:
    return {t.track_id for t in ts.tracks if t.state == "confirmed"}


def _log_size(run: Run, mid: str) -> int:
    path = run.tmp / f"{mid}.log"
    return path.stat().st_size if path.exists() else 0


def _standing_by(run: Run, mid: str, leader: str, log_from: int) -> bool:
    """``mid`` stands by for ``leader`` and has named its tracks after the leader's since its log had ``log_from``
    bytes."""
    st = run.status(mid)
    if st is None or st.role != "standby" or st.leader_id != leader:
        return False
    with (run.tmp / f"{mid}.log").open("rb") as f:
        f.seek(log_from)
        text = f.read().decode(errors="replace")
    return re.search(rf"standby {mid} follows {leader}: \d+ tracks renamed", text) is not None


def failover(run: Run, kills: int) -> list[dict[str, Any]]:
    """Kill the failover zone's leader ``kills`` times, each at a random instant once its standby is warm."""
    rng = random.Random(run.args.seed + 7)
    leader, standby = f"mgr-{FAILOVER_ZONE}-a", f"mgr-{FAILOVER_ZONE}-b"
    out = []
    log_from = 0
    for _ in range(kills):
        run.wait(lambda s=standby, ld=leader, n=log_from: _standing_by(run, s, ld, n), 60.0, f"{standby} warm")
        t_warm = time.monotonic()
        delay_s = rng.uniform(2.0, 6.0)
        while time.monotonic() < t_warm + delay_s:
            run.sample_cpu()
            time.sleep(0.1)
        before = run.sets_of(leader)
        last = _confirmed(before[-1][1]) if before else set()
        t_kill = time.time_ns()
        run.procs[leader].kill()
        run.procs[leader].wait(timeout=5)
        first = run.wait(lambda s=standby, t=t_kill: run.sets_of(s, t), 15.0, f"{standby}'s first TrackSet")
        t_first = first[0][0]
        run.wait(lambda s=standby, t=t_first: run.sets_of(s, t + 1_000_000_000), 10.0, "a second of tracks")
        after = set().union(*(_confirmed(ts) for a, ts in run.sets_of(standby, t_kill) if a <= t_first + 1e9))
        # A person the leader published may have walked on into a neighbour's zone meanwhile: kept if published.
        with run.lock:
            site = set().union(*(_confirmed(ts) for a, ts in run.sets if t_kill <= a <= t_first + 1e9))
        out.append(
            {
                "takeover_s": round((t_first - t_kill) / 1e9, 3),
                "ids_before": len(last),
                "ids_kept": len(last & (after | site)),
                "kept_share": round(len(last & (after | site)) / len(last), 4) if last else None,
                "kept_by_neighbours": sorted(last & (site - after)),
                "ids_lost": sorted(last - after - site),
                "other_zones": disturbance(run, t_kill, {leader, standby}),
            }
        )
        log_from = _log_size(run, leader)
        run.restarted.add(leader)
        run.start_manager(leader, FAILOVER_ZONE)  # restarted, it joins as standby
        leader, standby = standby, leader
    return out


def disturbance(run: Run, t_kill: int, skip: set[str]) -> dict[str, Any]:
    """The other managers' TrackSets around a kill: their longest gap in the 3 s after it against their usual
    interval, and lost sequence numbers; ``disturbed`` when a gap is over 5 intervals (and 0.5 s) or any is lost."""
    run.wait(lambda: time.time_ns() > t_kill + 3_000_000_000, 5.0, "three seconds after the kill")
    out: dict[str, Any] = {}
    for mid in sorted({ts.manager_id for _, ts in run.sets} - skip):
        arr = run.sets_of(mid, t_kill - 5_000_000_000)
        before = [a for a, _ in arr if a < t_kill]
        after = [(a, ts.seq) for a, ts in arr if t_kill <= a <= t_kill + 3_000_000_000]
        usual = statistics.median(np.diff(before)) / 1e9 if len(before) > 2 else math.nan
        gap = max(np.diff([t_kill] + [a for a, _ in after]), default=3e9) / 1e9
        lost = sum(b - a - 1 for (_, a), (_, b) in itertools.pairwise(after) if b > a + 1)
        out[mid] = {"gap_s": round(gap, 3), "usual_s": round(usual, 3), "seq_lost": lost}
    out["disturbed"] = any(v["gap_s"] > max(0.5, 5 * v["usual_s"]) or v["seq_lost"] for v in out.values())
    return out


# ---------------------------------------------------------------------------
# Scoring
# ---------------------------------------------------------------------------


def ground_truth(walkers: list[Walker], t0_s: float, t1_s: float) -> GroundTruth:
    frames: dict[int, list[GtPoint]] = {}
    for k in range(int(t0_s * GT_HZ) + 1, int(t1_s * GT_HZ) + 2):
        t_s = (k - 1) / GT_HZ
        frames[k] = [GtPoint(k, f"p{w.person_id}", *w.at(t_s)) for w in walkers]
    return GroundTruth(frames)


def _unique(hyps: dict[int, list[HypPoint]]) -> dict[int, list[HypPoint]]:
    """One point per track id and frame (an id published by two managers at once counts once)."""
    return {k: list({h.track_id: h for h in pts}.values()) for k, pts in hyps.items()}


def accuracy(sets: list[TrackSet], gt: GroundTruth, epoch_ns: int) -> tuple[dict[str, Any], dict[int, dict[str, str]]]:
    """Site-wide MOTA/IDF1 of every manager's tracks together, and each frame's person -> matched track."""
    hyps, frames = hypotheses_from_tracksets(sets, epoch_ns, GT_HZ, gt.frame_numbers)
    matched: dict[int, dict[str, str]] = {}

    def on_events(k: int, events: list[tuple[str, str, str, float]]) -> None:
        matched[k] = {o: h for kind, o, h, _ in events if kind in ("MATCH", "SWITCH")}

    m = evaluate_positions(gt, _unique(hyps), THRESHOLD_M, frames, on_events)
    keep = ("mota", "idf1", "motp_m", "recall", "precision", "id_switches", "false_positives", "misses", "track_ids")
    return {k: v for k, v in m.to_dict().items() if k in keep}, matched


def duplicates(sets: list[TrackSet], gt: GroundTruth, epoch_ns: int) -> dict[str, Any]:
    """Person-instants (a person at a scored frame, followed by some manager) published by more than one manager.

    At each frame every manager's tracks are matched one to one to the people (Hungarian, within the match
    distance, as the accuracy figures are); a person is published twice when a track of another manager than the
    one matched to them, matched to nobody and under another id, stands within the match distance of them too:
    an agent shows them as two people. ``same_id_share``: the person-instants where another manager's track
    beside them has the same id (a handover's or a takeover's overlap: agents merge one id of several managers
    into one row, and the accuracy figures count it once; a killed leader's last set counts for ``max_gap_s``
    of :func:`~user_agent.evaluate.hypotheses_from_tracksets` after it). ``near_several`` also
    counts, as a first version of this benchmark did, every person with tracks of two managers within the match
    distance: two people walking side by side across a border, each published by one manager, count there.
    """
    by_mgr: dict[str, list[TrackSet]] = {}
    for ts in sets:
        by_mgr.setdefault(ts.manager_id, []).append(ts)
    per = {m: hypotheses_from_tracksets(v, epoch_ns, GT_HZ, gt.frame_numbers)[0] for m, v in by_mgr.items()}
    seen = twice = same = near = 0
    for k, people in gt.frames.items():
        hyps = [(m, h) for m, by_frame in per.items() for h in by_frame.get(k, [])]
        if not people or not hyps:
            continue
        d = np.hypot(
            np.array([p.x_m for p in people])[:, None] - np.array([h.x_m for _, h in hyps])[None, :],
            np.array([p.y_m for p in people])[:, None] - np.array([h.y_m for _, h in hyps])[None, :],
        )
        close = d <= THRESHOLD_M
        rows, cols = linear_sum_assignment(np.where(close, d, 1e6))
        matched = {r: c for r, c in zip(rows.tolist(), cols.tolist(), strict=True) if close[r, c]}
        free = np.ones(len(hyps), dtype=bool)
        free[list(matched.values())] = False
        for i in range(len(people)):
            managers = {hyps[j][0] for j in np.flatnonzero(close[i])}
            near += len(managers) > 1
            if i not in matched:
                continue
            seen += 1
            mid, tid = hyps[matched[i]][0], hyps[matched[i]][1].track_id
            others = [hyps[j][1].track_id for j in np.flatnonzero(close[i]) if free[j] and hyps[j][0] != mid]
            twice += any(t != tid for t in others)
            same += tid in others
    share = round(twice / seen, 4) if seen else None
    return {
        "person_instants": seen,
        "by_several": twice,
        "share": share,
        "same_id_share": round(same / seen, 4) if seen else None,
        "near_several": near,
    }


def crossings(gt: GroundTruth, matched: dict[int, dict[str, str]]) -> dict[str, Any]:
    """Border crossings (a person's zone changes between frames) whose matched track is the same just before and
    just after (within CROSSING_WINDOW_S); crossings without a matched track on both sides are not judged."""
    w = int(CROSSING_WINDOW_S * GT_HZ)
    ks = sorted(gt.frames)
    zone = {k: {p.person_id: zone_of(p.x_m, p.y_m) for p in gt.frames[k]} for k in ks}
    total = judged = kept = 0
    for a, b in itertools.pairwise(ks):
        for pid, z in zone[b].items():
            if zone[a].get(pid, z) == z:
                continue
            total += 1
            pre = next((matched[k][pid] for k in range(a, a - w, -1) if pid in matched.get(k, {})), None)
            post = next((matched[k][pid] for k in range(b, b + w) if pid in matched.get(k, {})), None)
            if pre and post:
                judged += 1
                kept += pre == post
    return {"crossings": total, "judged": judged, "kept_id": kept, "share": round(kept / judged, 4) if judged else None}


def _cpu_util(run: Run, name: str) -> float | None:
    xs = run.cpu.get(name, [])
    if len(xs) < 2 or xs[-1][0] <= xs[0][0] or name in run.restarted:
        return None
    return round((xs[-1][1] - xs[0][1]) / (xs[-1][0] - xs[0][0]), 4)


def manager_figures(run: Run, mid: str, sent: dict[str, int], warm_ns: int) -> dict[str, Any]:
    with run.lock:
        sts = [st for a, st in run.statuses if st.manager_id == mid]
        warm = [st for a, st in run.statuses if st.manager_id == mid and a >= warm_ns and st.tick_rate_hz > 0]
    last = sts[-1] if sts else None
    expected = sum(sent.get(sid, 0) for sid in (last.sensors_expected if last else []))
    sets = run.sets_of(mid, warm_ns)
    return {
        "zone": last.zone if last else None,
        "cameras": len(last.sensors_expected) if last else None,
        "tick_ms": round(statistics.median(st.tick_ms for st in warm), 2) if warm else None,
        "tick_p99_ms": round(max(st.tick_p99_ms for st in warm), 2) if warm else None,
        "tick_cpu_ms": round(statistics.median(st.tick_cpu_ms for st in warm), 2) if warm else None,
        "tick_rate_hz": round(statistics.median(st.tick_rate_hz for st in warm), 2) if warm else None,
        "tracks_mean": round(statistics.fmean(len(ts.tracks) for _, ts in sets), 2) if sets else 0.0,
        "frames_lost": expected - last.frames_received if last and expected and mid not in run.restarted else None,
        "dropped_msgs": last.dropped_msgs if last else None,
        "refused_msgs": last.refused_msgs if last else None,
        "refused_per_s": round(last.refused_msgs / run.span_s, 1) if last and run.span_s else None,
        "cpu_cores": _cpu_util(run, mid),
        "latency_split_ms": _latency_split(warm),
    }


LATENCY_PARTS = ("age_p50_ms", "node_ms", "transport_ms", "wait_ms", "fusion_ms", "publish_ms")
"""Where a manager's capture -> publish time went (``ManagerStatus.latency``)."""


def _latency_split(statuses: list[ManagerStatus]) -> dict[str, float] | None:
    """Medians over the run's status periods of each part of a manager's capture -> publish time."""
    parts = [st.latency for st in statuses if st.latency is not None]
    if not parts:
        return None
    return {k: round(statistics.median(getattr(lat, k) for lat in parts), 2) for k in LATENCY_PARTS}


def score_run(run: Run, cams: list[Cam], walkers: list[Walker], managers: dict[str, str]) -> dict[str, Any]:
    args = run.args
    fleet = json.loads((run.tmp / "fleet.json").read_text()) if (run.tmp / "fleet.json").exists() else {}
    warm_ns = run.epoch_ns + int(args.warmup * 1e9)
    with run.lock:
        sets = [ts for _, ts in run.sets]
        lat = [(a - ts.stamp_ns) / 1e6 for a, ts in run.sets if a >= warm_ns]
    end_s = max(((ts.stamp_ns - run.epoch_ns) / 1e9 for ts in sets), default=args.warmup)
    gt = ground_truth(walkers, args.warmup, end_s - 0.5)
    acc, matched = accuracy(sets, gt, run.epoch_ns)
    sent = fleet.get("per_sensor", {})
    figures = {
        m: manager_figures(run, m, sent, warm_ns) for m in sorted({ts.manager_id for ts in sets} | set(managers))
    }
    lost = [f["frames_lost"] for f in figures.values() if f["frames_lost"] is not None]
    return {
        "managers": figures,
        "accuracy": acc,
        "published_twice": duplicates(sets, gt, run.epoch_ns),
        "border_crossings": crossings(gt, matched),
        "latency_ms": _percentiles(lat),
        "frames_lost": sum(lost) if lost else None,
        "fleet": {
            "sent": fleet.get("sent"),
            "frames_per_s": round(fleet["sent"] / max(end_s, 1e-9), 1) if fleet.get("sent") else None,
            "asked_frames_per_s": args.sensors * args.fps,
            "behind_ms_max": fleet.get("behind_ms_max"),
            "kept_up": fleet.get("behind_ms_max", math.inf) <= 1e3 / args.fps,
            "cpu_cores": _cpu_util(run, "fleet"),
        },
        "router_cpu_cores": _cpu_util(run, "router"),
        "logs": str(run.tmp),
    }


# ---------------------------------------------------------------------------
# The host estimate, and the driver
# ---------------------------------------------------------------------------


def hosts_estimate(args: argparse.Namespace, single: dict[str, Any], zones: dict[str, Any]) -> dict[str, Any]:
    """Fit ``cores = a * fused camera-frames/s + b * person-ticks/s + c * refused frames/s`` to every measured
    manager (non-negative least squares), and the router's cores per frame/s it delivers; apply them to 1,000
    cameras and 1,000 people cut into zones like the hall's (the cameras and people each zone shares with its
    neighbours counted in each, as measured). Two cases: as measured (a zone manager is sent every camera's frames
    and refuses those not its own), and with each manager sent only its own cameras' frames."""
    from scipy.optimize import nnls

    rows, ys = [], []
    for f in (*single["managers"].values(), *zones["managers"].values()):
        if f["cpu_cores"] is not None and f["cameras"] and f["tick_rate_hz"]:
            rows.append([f["cameras"] * args.fps, f["tracks_mean"] * f["tick_rate_hz"], f["refused_per_s"] or 0.0])
            ys.append(f["cpu_cores"])
    if len(rows) < 3:
        return {"error": "too few managers with CPU figures to fit the model"}
    (a, b, c), residual = nnls(np.array(rows), np.array(ys))
    zm = list(zones["managers"].values())
    cam_share = sum(f["cameras"] or 0 for f in zm) / args.sensors
    person_share = sum(f["tracks_mean"] for f in zm) / max(args.people, 1)
    rate = statistics.fmean(f["tick_rate_hz"] or args.rate_hz for f in zm)
    delivered = sum((f["cameras"] or 0) for f in zm) * args.fps
    router_per_frame = (zones["router_cpu_cores"] or 0.0) / delivered if delivered else 0.0
    n_cam, n_people, fps = int(ESTIMATE_SITE["cameras"]), int(ESTIMATE_SITE["people"]), ESTIMATE_SITE["fps"]
    zones_needed = math.ceil(len(zm) * n_cam / args.sensors)
    own = a * n_cam * fps * cam_share + b * n_people * person_share * rate
    refused = c * zones_needed * n_cam * fps * (1 - cam_share / zones_needed)
    router = router_per_frame * n_cam * fps * cam_share
    cores = os.cpu_count() or 1

    def hosts(x: float) -> int:
        return math.ceil(x / (cores * 0.7))

    return {
        "model": "cores = a*camera_frames/s*camera_share + b*people*person_share*tick_hz + c*refused_frames/s + router",
        "a_core_s_per_fused_frame": float(a),
        "b_core_s_per_person_tick": float(b),
        "c_core_s_per_refused_frame": float(c),
        "fit_points": len(rows),
        "fit_residual_cores": round(float(residual), 4),
        "router_core_s_per_frame": router_per_frame,
        "camera_share": round(cam_share, 3),
        "person_share": round(person_share, 3),
        "tick_hz": round(rate, 2),
        "site": {**ESTIMATE_SITE, "zones": zones_needed, "cameras_per_zone": args.sensors / len(zm)},
        "cores_per_host": cores,
        "host_load": 0.7,
        "as_measured": {"cores": round(own + refused + router, 2), "hosts": hosts(own + refused + router)},
        "own_frames_only": {"cores": round(own + router, 2), "hosts": hosts(own + router)},
    }


def compare(single: dict[str, Any], zones: dict[str, Any]) -> dict[str, Any]:
    def diff(key: str) -> float | None:
        a, b = zones["accuracy"].get(key), single["accuracy"].get(key)
        return round(a - b, 4) if a is not None and b is not None else None

    def ratios(key: str) -> tuple[float | None, float | None]:
        """The zone managers' ``key`` over the single manager's: (largest, mean)."""
        s_tick = next(iter(single["managers"].values()))[key]
        z_ticks = [f[key] for f in zones["managers"].values() if f[key] is not None]
        if not z_ticks or not s_tick:
            return None, None
        return round(max(z_ticks) / s_tick, 3), round(statistics.fmean(z_ticks) / s_tick, 3)

    (wall_max, wall_mean), (cpu_max, cpu_mean) = ratios("tick_ms"), ratios("tick_cpu_ms")
    return {
        "mota_zones_minus_single": diff("mota"),
        "idf1_zones_minus_single": diff("idf1"),
        "tick_ratio_max": wall_max,
        "tick_ratio_mean": wall_mean,
        "tick_cpu_ratio_max": cpu_max,
        "tick_cpu_ratio_mean": cpu_mean,
    }


def targets(result: dict[str, Any]) -> dict[str, Any]:
    z, c, kills = result["zones"], result["zone_vs_single"], result["failover"].get("kills", [])

    def within(x: float | None, lo: float, hi: float) -> bool:
        return x is not None and lo <= x <= hi

    return {
        "accuracy_within_0_01": within(c["mota_zones_minus_single"], -0.01, 0.01)
        and within(c["idf1_zones_minus_single"], -0.01, 0.01),
        "published_twice_le_0_5pct": within(z["published_twice"]["share"], 0.0, 0.005),
        "crossings_kept_ge_99pct": within(z["border_crossings"]["share"], 0.99, 1.0),
        "tick_ratio_le_0_35": within(c["tick_ratio_max"], 0.0, 0.35),
        "tick_cpu_ratio_le_0_35": within(c["tick_cpu_ratio_max"], 0.0, 0.35),
        "latency_p50_le_60ms": within(z["latency_ms"]["p50"], 0.0, 60.0),
        "latency_p99_le_120ms": within(z["latency_ms"]["p99"], 0.0, 120.0),
        "zero_frames_lost": z["frames_lost"] == 0,
        "takeover_le_2s": bool(kills) and all(k["takeover_s"] <= 2.0 for k in kills),
        "kept_ids_ge_95pct": bool(kills) and all((k["kept_share"] or 0) >= 0.95 for k in kills),
        "other_zones_undisturbed": bool(kills) and not any(k["other_zones"]["disturbed"] for k in kills),
    }


def parse(argv: list[str] | None) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="bench_zones", description=__doc__.split("\n\n")[0])
    sub = p.add_subparsers(dest="cmd")
    f = sub.add_parser("fleet", help="play the hall's cameras only (used by the benchmark)")
    for q in (p, f):
        q.add_argument("--sensors", type=int, default=64)
        q.add_argument("--fps", type=float, default=30.0)
        q.add_argument("--people", type=int, default=60)
        q.add_argument("--duration", type=float, default=60.0, help="seconds of each run (fleet: 0 = until SIGTERM)")
        q.add_argument("--seed", type=int, default=1)
        q.add_argument("--range-m", type=float, default=8.0, help="how far a camera sees people")
    p.add_argument("--zone-reach-m", type=float, default=3.0, help="a zone's cameras: inside it or this close")
    p.add_argument("--rate-hz", type=float, default=10.0, help="managers' most fusions per second")
    p.add_argument("--kills", type=int, default=5, help="failover: times the zone's leader is SIGKILLed")
    p.add_argument("--warmup", type=float, default=5.0, help="seconds left out of the figures")
    p.add_argument("--quick", action="store_true", help="a smoke run: 8 cameras, 8 people, 8 s, 2 kills")
    p.add_argument("--runs", default="single,zones,failover", help="which runs (comma-separated)")
    p.add_argument("--out", type=Path, default=None, help="also write the JSON here")
    f.add_argument("--connect", required=True)
    f.add_argument("--prefix", default=PREFIX)
    f.add_argument("--epoch-ns", type=int, default=0)
    f.add_argument("--stats", type=Path, default=None)
    args = p.parse_args(argv)
    if args.cmd is None and args.quick:  # the quick sizes, where no flag gave another
        for key, value in QUICK.items():
            if getattr(args, key) == p.get_default(key):
                setattr(args, key, value)
    return args


def fleet_main(args: argparse.Namespace) -> int:
    args.only, args.clock_offset_ms, args.reorder, args.late_ms = "", 0.0, 0, 0.0
    stats = run_fleet(args, make_hall(args.sensors, args.people, args.seed), args.range_m)
    if args.stats:
        args.stats.write_text(json.dumps(stats.__dict__))
    return 0


def main(argv: list[str] | None = None) -> int:
    args = parse(argv)
    if args.cmd == "fleet":
        return fleet_main(args)
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))  # stop the site's processes on the way out
    zones = {f"mgr-{z}": z for z in ZONES}
    runs = args.runs.split(",")
    result: dict[str, Any] = {"benchmark": "bench_zones", "sensors": args.sensors, "fps": args.fps}
    result |= {"people": args.people, "duration_s": args.duration, "seed": args.seed, "range_m": args.range_m}
    result |= {"zone_reach_m": args.zone_reach_m, "manager_max_rate_hz": args.rate_hz, "cores": os.cpu_count()}
    result["single"] = run_site(args, "single", {"mgr-site": ""}) if "single" in runs else None
    result["zones"] = run_site(args, "zones", zones) if "zones" in runs else None
    if "failover" in runs:
        fz = {**{m: z for m, z in zones.items() if z != FAILOVER_ZONE}, f"mgr-{FAILOVER_ZONE}-a": FAILOVER_ZONE}
        fz[f"mgr-{FAILOVER_ZONE}-b"] = FAILOVER_ZONE
        result["failover"] = run_site(args, "failover", fz, kills=args.kills)
    if result["single"] and result["zones"]:
        result["zone_vs_single"] = compare(result["single"], result["zones"])
        result["hosts_estimate"] = hosts_estimate(args, result["single"], result["zones"])
        if result.get("failover"):
            result["targets"] = targets(result)
    text = json.dumps(result, indent=2)
    if args.out:
        args.out.write_text(text + "\n")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
