"""Tracking under floods of schema-valid hostile messages (issue 15): recall per 4 s window, recorder lag, CPU, RSS.

Usage::

    python -m benchmarks.bench_flood [--seed 5] [--phase-s 12] [--gap-s 12] [--out FILE]
    python -m benchmarks.bench_flood --clean          # the same schedule, no attacker: the clean run
    python -m benchmarks.bench_flood --site demo [--seed 7] [--clean]   # against `panostereo demo`

A live site on loopback (real processes, multicast scouting off): a ``panostereo router``, a
``panostereo manager`` that fuses the site's four sensors, four ``panostereo node`` processes playing
detection files of a room with three people walking (``benchmarks.bench_load``: the faults tests'
site), an ``agent record`` of everything, and this process as the watching agent. On a schedule fixed
relative to the world's epoch (so a clean run of the same seed watches the same people at the same
instants):

``before`` (``gap_s``), ``fresh`` flood (``phase_s``: messages under fresh sensor ids only), ``after
fresh`` (``gap_s``), ``real`` flood (``phase_s``: half of the messages under the site's own ids),
``after real`` (``gap_s``).

Each flood is one client (``benchmarks.hostile flood``) sending as fast as it can. Recall of a TrackSet
= people with a confirmed track within 0.5 m (one to one, nearest first) / people, at the TrackSet's
fusion instant; a window's recall is the mean over the TrackSets that arrived in it (a window with none
scores 0: the manager said nothing), and second by second after each flood. Printed JSON: recall per
4 s window per phase, the attacker's
rates, the recorder's worst lag and drops (from its file), every process's CPU seconds and peak RSS,
and whether all stayed up.

``--site demo`` runs the schedule against ``panostereo demo`` (four rendered cameras, the PTZ head; the
conditions of the issue), starting 35 s after launch; recall then comes from the demo's own recording
and ground truth, and its summary (what the recording lost, the sensors it did not start) is included.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import subprocess
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parent.parent
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from benchmarks.bench_load import Walker  # noqa: E402
from common.schema import TrackSet  # noqa: E402

__all__ = ["Schedule", "recall_of", "run", "window_recalls"]

WINDOW_S = 4.0
MATCH_M = 0.5


@dataclass(frozen=True, slots=True)
class Schedule:
    """Phase boundaries in seconds after the start of ``before``."""

    gap_s: float = 12.0
    phase_s: float = 12.0

    def phases(self) -> list[tuple[str, float, float]]:
        g, p = self.gap_s, self.phase_s
        marks = [("before", g), ("fresh", p), ("after fresh", g), ("real", p), ("after real", g)]
        out, t = [], 0.0
        for name, length in marks:
            out.append((name, t, t + length))
            t += length
        return out


def recall_of(ts: TrackSet, walkers: list[Walker], epoch_ns: int, loop_s: float) -> float:
    """Fraction of the people with a confirmed track within MATCH_M at the TrackSet's instant (one to one)."""
    t_s = (ts.stamp_ns - epoch_ns) / 1e9 % loop_s
    return _recall([w.at(t_s) for w in walkers], ts)


def _recall(people: list[tuple[float, float]], ts: TrackSet) -> float:
    tracks = [(t.x_m, t.y_m) for t in ts.tracks if t.state == "confirmed"]
    pairs = sorted(
        (math.hypot(px - tx, py - ty), i, j) for i, (px, py) in enumerate(people) for j, (tx, ty) in enumerate(tracks)
    )
    used_p: set[int] = set()
    used_t: set[int] = set()
    for d, i, j in pairs:
        if d > MATCH_M:
            break
        if i not in used_p and j not in used_t:
            used_p.add(i)
            used_t.add(j)
    return len(used_p) / len(people) if people else 1.0


def window_recalls(
    scored: list[tuple[float, float]], start: float, end: float, window_s: float = WINDOW_S
) -> list[float]:
    """Mean recall per ``window_s`` window of [start, end) from (arrival, recall) pairs; 0 for a silent window."""
    out = []
    t = start
    while t + window_s <= end + 1e-6:
        got = [r for a, r in scored if t <= a < t + window_s]
        out.append(round(sum(got) / len(got), 3) if got else 0.0)
        t += window_s
    return out


@dataclass
class ProcStats:
    cpu_s: dict[str, float] = field(default_factory=dict)
    rss_peak_mib: dict[str, float] = field(default_factory=dict)


def _proc_sample(pid: int) -> tuple[float, float]:
    """(CPU seconds, RSS MiB) of a process from /proc."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        status = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return 0.0, 0.0
    import os

    tick = os.sysconf("SC_CLK_TCK")
    cpu = (int(stat[11]) + int(stat[12])) / tick
    rss = next((int(ln.split()[1]) / 1024 for ln in status.splitlines() if ln.startswith("VmRSS:")), 0.0)
    return cpu, rss


@contextlib.contextmanager
def _site(tmp: Path, seed: int) -> Iterator[Any]:
    from tests.integration.test_faults import make_fault_site

    site = make_fault_site(tmp, prefix="flood")
    try:
        yield site
    finally:
        site.stop_all()


def run(
    tmp: Path,
    *,
    seed: int = 5,
    schedule: Schedule | None = None,
    clean: bool = False,
    record: bool = True,
    start_world_s: float | None = 30.0,
    block: bool = False,
) -> dict[str, Any]:
    """Run the schedule against a fresh site; return the figures (see the module docstring)."""
    import tests.integration.test_faults as tf
    from tests.integration.test_faults import LOOP_S, observing, start_tracking
    from user_agent.evaluate import unseen_spans
    from user_agent.recording import load_recording, read_metadata

    sched = schedule or Schedule()
    old_seed, tf.SEED = tf.SEED, seed
    stats = ProcStats()
    result: dict[str, Any] = {
        "seed": seed,
        "clean": clean,
        "block": block,
        "window_s": WINDOW_S,
        "schedule": sched.phases(),
    }
    with _site(tmp, seed) as site:
        site.start_router()
        with observing(site) as obs:
            start_tracking(site, obs)
            rec_path = tmp / "flood.mcap"
            recorder = None
            if record:
                recorder = site._spawn(
                    [sys.executable, "-m", "panostereo", "agent", "record", str(rec_path), "--prefix", site.prefix,
                     "--connect", site.endpoint, "--agent-id", "recorder"],
                    "recorder",
                )  # fmt: skip
                time.sleep(1.0)
            # The schedule starts at a fixed world time (modulo the people's loop), so a clean run of the same
            # seed watches the same people at the same instants.
            # None: a second from now (a run compared only with its own "before").
            t_world = (time.time_ns() - site.epoch_ns) / 1e9
            start_world = t_world + 1.0 if start_world_s is None else start_world_s
            while start_world < t_world + 1.0:
                start_world += LOOP_S
            time.sleep(max(0.0, start_world - t_world))
            t0 = time.monotonic()
            result["start_world_s"] = start_world
            procs = {p.name: p for p in site.procs}
            peak = dict.fromkeys(procs, 0.0)
            cpu0 = {n: _proc_sample(p.pid)[0] for n, p in procs.items()}
            attacks: dict[str, Any] = {}
            for name, a, b in sched.phases():
                while time.monotonic() - t0 < a:
                    time.sleep(0.05)
                attacker = None
                if name in ("fresh", "real") and not clean:
                    attacker = subprocess.Popen(
                        [sys.executable, "-m", "benchmarks.hostile", "flood", "--connect", site.endpoint,
                         "--prefix", site.prefix, "--real", ",".join(site.ids), "--manager", "mgr1",
                         "--real-share", "0.5" if name == "real" else "0.0", "--duration", str(b - a),
                         "--seed", str(seed), *(["--block"] if block else [])],
                        cwd=REPO, stdout=subprocess.PIPE, text=True,
                    )  # fmt: skip
                while time.monotonic() - t0 < b:
                    for n, p in procs.items():
                        if p.alive:
                            peak[n] = max(peak[n], _proc_sample(p.pid)[1])
                    time.sleep(0.25)
                if attacker is not None:
                    out, _ = attacker.communicate(timeout=30)
                    lines = [json.loads(x) for x in out.splitlines() if x.startswith("{")]
                    attacks[name] = lines[-1] if lines else {}
            stats.cpu_s = {n: round(_proc_sample(p.pid)[0] - cpu0[n], 1) for n, p in procs.items()}
            stats.rss_peak_mib = {n: round(v, 1) for n, v in peak.items()}
            scored = [
                (a - t0, recall_of(ts, site.walkers, site.epoch_ns, LOOP_S)) for a, ts in list(obs.sets) if a >= t0
            ]
            result["recall"] = {name: window_recalls(scored, a, b) for name, a, b in sched.phases()}
            # After each flood, second by second: how soon tracking is back.
            result["recall_1s_after"] = {
                name: window_recalls(scored, a, b, 1.0) for name, a, b in sched.phases() if name.startswith("after")
            }
            result["attacker"] = attacks
            result["alive"] = {n: p.alive for n, p in procs.items()}
            last = obs.status_since(t0)
            if last:
                st = last[-1]
                result["manager"] = {
                    "refused_msgs": st.refused_msgs,
                    "refused_partial": st.refused_partial,
                    "refused": {r.sender_id: [r.unlisted, r.wrong_id, r.skewed, r.ahead] for r in st.refused[:8]},
                    "decode_errors": st.decode_errors,
                    "dropped_msgs": st.dropped_msgs,
                }
            if recorder is not None:
                recorder.signal(2)
                recorder.wait(60)
                meta = read_metadata(rec_path)
                sets = load_recording(rec_path).tracksets
                result["recorder_tracks"] = {
                    "tracksets": len(sets),
                    "lost_s": round(sum(b - a for a, b in unseen_spans(sets)) / 1e9, 2),
                }
                result["recorder"] = {
                    k: meta.get(k) for k in ("written", "dropped", "dropped_raw", "max_lag_s")
                } | {"top_drops": sorted(
                    ((k.split(":", 1)[1], int(v)) for k, v in meta.items() if k.startswith("dropped:")),
                    key=lambda kv: -kv[1])[:5]}  # fmt: skip
    result["cpu_s"] = stats.cpu_s
    result["rss_peak_mib"] = stats.rss_peak_mib
    tf.SEED = old_seed
    return result


def run_demo(tmp: Path, *, seed: int = 7, schedule: Schedule | None = None, clean: bool = False,
             lead_s: float = 35.0, rate: float = 0.0) -> dict[str, Any]:  # fmt: skip
    """The same schedule against ``panostereo demo`` (the embedded site, rendered cameras), ``lead_s`` after its
    start; recall from its own recording and ground truth (TrackSets by fusion instant, people at the nearest
    ground-truth frame)."""
    from tests.support import free_port
    from user_agent.groundtruth import read_gt_csv
    from user_agent.recording import load_recording

    sched = schedule or Schedule()
    phases = sched.phases()
    out = tmp / "demo"
    port = free_port()
    duration = lead_s + phases[-1][2] + 2.0
    t_launch = time.time_ns()
    demo = subprocess.Popen(
        [sys.executable, "-m", "panostereo", "demo", "--duration", str(duration), "--seed", str(seed), "--out",
         str(out), "--listen", f"tcp/127.0.0.1:{port}", "--no-view"],
        cwd=REPO, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )  # fmt: skip
    attacks: dict[str, Any] = {}
    t0 = time.monotonic() + lead_s
    for name, a, b in phases:
        while time.monotonic() - t0 < a:
            time.sleep(0.05)
        if name in ("fresh", "real") and not clean:
            out_text = subprocess.run(
                [sys.executable, "-m", "benchmarks.hostile", "flood", "--connect", f"tcp/127.0.0.1:{port}",
                 "--prefix", "pano", "--real", "pano1,pano2,pano3,ptz1", "--manager", "mgr1",
                 "--real-share", "0.5" if name == "real" else "0.0", "--duration", str(b - a), "--seed", str(seed),
                 "--rate", str(rate)],
                cwd=REPO, capture_output=True, text=True, timeout=b - a + 60, check=False,
            ).stdout  # fmt: skip
            lines = [json.loads(x) for x in out_text.splitlines() if x.startswith("{")]
            attacks[name] = lines[-1] if lines else {}
    rc = demo.wait(timeout=600)
    rec = load_recording(out / "recording.mcap")
    gt = read_gt_csv(out / "gt.csv")
    epoch, fps = rec.meta_int("epoch_ns", 0), rec.meta_float("fps", 15.0)
    start_world = (t_launch - epoch) / 1e9 + lead_s
    scored = []
    for ts in rec.tracksets:
        k = round((ts.stamp_ns - epoch) / 1e9 * fps) + 1
        if k in gt.frames:
            people = [(p.x_m, p.y_m) for p in gt.frames[k]]
            scored.append(((ts.stamp_ns - epoch) / 1e9 - start_world, _recall(people, ts)))
    summary = json.loads((out / "summary.json").read_text()) if (out / "summary.json").exists() else {}
    return {
        "site": "demo",
        "seed": seed,
        "rate_limit_hz": rate,
        "clean": clean,
        "returncode": rc,
        "window_s": WINDOW_S,
        "schedule": phases,
        "recall": {name: window_recalls(scored, a, b) for name, a, b in phases},
        "recall_1s_after": {
            name: window_recalls(scored, a, b, 1.0) for name, a, b in phases if name.startswith("after")
        },
        "attacker": attacks,
        "summary": {
            k: summary.get(k)
            for k in ("mota", "recall", "recording_lost", "sensors_not_started", "refused_by_manager", "restarts")
        },
    }


def main(argv: list[str] | None = None) -> int:
    import tempfile

    p = argparse.ArgumentParser(prog="benchmarks.bench_flood", description=__doc__.split("\n\n")[0])
    p.add_argument("--seed", type=int, default=5)
    p.add_argument("--phase-s", type=float, default=12.0, help="length of each flood")
    p.add_argument("--gap-s", type=float, default=12.0, help="before, and after each flood")
    p.add_argument("--clean", action="store_true", help="no attacker: the clean run of the same schedule")
    p.add_argument("--no-record", action="store_true", help="no `agent record` beside the site")
    p.add_argument("--block", action="store_true", help="the attacker uses BLOCK congestion control (default DROP)")
    p.add_argument("--start-world-s", type=float, default=30.0, help="world time the schedule starts at")
    p.add_argument("--rate", type=float, default=0.0, help="--site demo: cap the attacker at this many msg/s (0: none)")
    p.add_argument(
        "--site",
        choices=["faults", "demo"],
        default="faults",
        help="faults: detection-file nodes (default); demo: `panostereo demo` with its rendered cameras",
    )
    p.add_argument("--out", default=None, help="also write the JSON here")
    args = p.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="bench-flood-") as tmp:
        if args.site == "demo":
            res = run_demo(
                Path(tmp), seed=args.seed, schedule=Schedule(args.gap_s, args.phase_s), clean=args.clean, rate=args.rate
            )
            print(json.dumps(res, indent=1))
            if args.out:
                Path(args.out).write_text(json.dumps(res, indent=1) + "\n")
            return 0
        res = run(
            Path(tmp),
            seed=args.seed,
            schedule=Schedule(args.gap_s, args.phase_s),
            clean=args.clean,
            record=not args.no_record,
            start_world_s=args.start_world_s,
            block=args.block,
        )
    text = json.dumps(res, indent=1)
    print(text)
    if args.out:
        Path(args.out).write_text(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
