"""Memory over a long run: the demo for an hour, every process's RSS every 30 s, IDF1 per 10-minute window.

Usage::

    python -m benchmarks.bench_soak [--duration 3600] [--sample-s 30] [--window-s 600] [--warmup-s 600]
                                    [--seed 7] [--out DIR] [--json FILE]

Runs ``panostereo demo`` (the embedded site, every process its own, on a free loopback port) for
``--duration`` seconds and samples the resident memory of each of its processes (router, camera nodes,
manager, and the demo's own recorder and live view) from ``/proc`` every ``--sample-s``. At the end the
demo scores its recording; here the same tracks are scored per ``--window-s`` window (IDF1, MOTA,
recall, ID switches), so a slow decline shows.

Printed JSON: per process, RSS at the first sample, at the end of ``--warmup-s`` and at the end, its
growth after warm-up as a least-squares slope in MB per hour (the goal: at most 5 MB/h in every
process: memory bounded by configuration, not by uptime) and every sample; the windows' scores; and
the demo's summary.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parent.parent
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

__all__ = ["growth_mb_per_h", "main", "process_name"]

GOAL_MB_PER_H = 5.0


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _children(pid: int) -> list[int]:
    """Every descendant of ``pid`` (from /proc)."""
    parents: dict[int, int] = {}
    for d in os.listdir("/proc"):
        if not d.isdigit():
            continue
        try:
            stat = Path(f"/proc/{d}/stat").read_text()
        except OSError:
            continue
        # The command name is in parentheses and may hold spaces: the fields after it are fixed.
        parents[int(d)] = int(stat.rsplit(")", 1)[1].split()[1])
    out, todo = [], [pid]
    while todo:
        p = todo.pop()
        kids = [c for c, pp in parents.items() if pp == p]
        out += kids
        todo += kids
    return out


def process_name(cmdline: list[str]) -> str:
    """A readable name for one of the demo's processes from its command line."""
    args = [a for a in cmdline if a]
    if "demo" in args:
        return "demo"
    if "router" in args:
        return "router"
    if "manager" in args:
        return "manager"
    if "--config" in args:
        cfg = args[args.index("--config") + 1]
        return Path(cfg).stem
    return Path(args[0]).name if args else "?"


def _rss_mb(pid: int) -> float | None:
    try:
        text = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return None
    m = re.search(r"^VmRSS:\s+(\d+) kB", text, re.M)
    return int(m.group(1)) / 1024.0 if m else None


def _cmdline(pid: int) -> list[str]:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().decode(errors="replace").split("\0")
    except OSError:
        return []


def growth_mb_per_h(samples: list[tuple[float, float]], after_s: float) -> float | None:
    """Least-squares slope of (t_s, rss_mb) samples taken at or after ``after_s``, in MB per hour."""
    pts = [(t, v) for t, v in samples if t >= after_s]
    if len(pts) < 3:
        return None
    n = len(pts)
    mt = sum(t for t, _ in pts) / n
    mv = sum(v for _, v in pts) / n
    var = sum((t - mt) ** 2 for t, _ in pts)
    if var <= 0:
        return None
    return sum((t - mt) * (v - mv) for t, v in pts) / var * 3600.0


def _windows(run_dir: Path, window_s: float, threshold_m: float) -> list[dict[str, Any]]:
    """Scores of the demo's recording per ``window_s`` of its scored frames."""
    from user_agent.evaluate import evaluate_positions
    from user_agent.groundtruth import read_gt_csv
    from user_agent.recording import load_recording
    from user_agent.report import score_recording

    rec = load_recording(run_dir / "recording.mcap")
    gt = read_gt_csv(run_dir / "gt.csv")
    scored = score_recording(rec, gt, threshold_m=threshold_m)
    fps = rec.meta_float("fps", -1.0)
    frames = sorted(scored.hypotheses)
    if not frames or fps <= 0:
        return []
    per = max(1, round(window_s * fps))
    out = []
    for i in range(0, len(frames), per):
        chunk = frames[i : i + per]
        m = evaluate_positions(gt, scored.hypotheses, threshold_m, frames=chunk)
        out.append(
            {
                "from_s": round((chunk[0] - 1) / fps, 1),
                "to_s": round(chunk[-1] / fps, 1),
                "idf1": round(m.idf1, 4),
                "mota": round(m.mota, 4),
                "recall": round(m.recall, 4),
                "id_switches": m.id_switches,
            }
        )
    return out


def run(args: argparse.Namespace) -> dict[str, Any]:
    out = Path(args.out or f"runs/soak-{time.strftime('%Y%m%d-%H%M%S')}")
    out.mkdir(parents=True, exist_ok=True)
    port = _free_port()
    cmd = [
        sys.executable,
        "-m",
        "panostereo",
        "demo",
        "--duration",
        str(args.duration),
        "--seed",
        str(args.seed),
        "--no-view",
        "--listen",
        f"tcp/127.0.0.1:{port}",
        "--out",
        str(out / "run"),
    ]
    log = (out / "demo.log").open("w")
    demo = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)

    def _stop(_signum: int, _frame: Any) -> None:
        raise KeyboardInterrupt

    signal.signal(signal.SIGTERM, _stop)  # stopped early: the demo stops too, and scores what it ran
    samples: dict[str, list[tuple[float, float]]] = {}
    scoring: dict[str, float] = {}
    """RSS of the demo's own process once the site's processes are gone (it then loads and scores the recording:
    not the run's memory, so kept out of the growth fit)."""
    t0 = time.monotonic()
    running = False
    try:
        while demo.poll() is None:
            t = time.monotonic() - t0
            kids = _children(demo.pid)
            running = running or len(kids) > 1
            if running and len(kids) <= 1:  # the site stopped (a router may be all that is left)
                rss = _rss_mb(demo.pid)
                if rss is not None:
                    scoring["demo"] = max(scoring.get("demo", 0.0), round(rss, 1))
                kids = []
            for pid in [demo.pid, *kids] if not scoring else []:
                rss = _rss_mb(pid)
                name = process_name(_cmdline(pid))
                if rss is not None and name not in ("python", "python3", "?"):
                    samples.setdefault(name, []).append((round(t, 1), round(rss, 1)))
            deadline = time.monotonic() + args.sample_s
            while demo.poll() is None and time.monotonic() < deadline:
                time.sleep(0.5)
    except KeyboardInterrupt:
        os.killpg(demo.pid, signal.SIGINT)
        demo.wait(120)
    finally:
        log.close()
    elapsed = time.monotonic() - t0
    procs = {}
    for name, pts in sorted(samples.items()):
        warm = [v for t, v in pts if t >= args.warmup_s]
        slope = growth_mb_per_h(pts, args.warmup_s)
        procs[name] = {
            "rss_first_mb": pts[0][1],
            "rss_after_warmup_mb": warm[0] if warm else None,
            "rss_last_mb": pts[-1][1],
            "rss_max_mb": max(v for _, v in pts),
            "rss_scoring_mb": scoring.get(name),
            "growth_after_warmup_mb_per_h": None if slope is None else round(slope, 2),
            "within_goal": None if slope is None else slope <= GOAL_MB_PER_H,
            "samples": pts,
        }
    summary_path = out / "run" / "summary.json"
    summary = json.loads(summary_path.read_text()) if summary_path.is_file() else {}
    windows = _windows(out / "run", args.window_s, args.threshold) if summary else []
    return {
        "duration_s": args.duration,
        "elapsed_s": round(elapsed, 1),
        "sample_s": args.sample_s,
        "warmup_s": args.warmup_s,
        "seed": args.seed,
        "demo_exit": demo.returncode,
        "goal_mb_per_h": GOAL_MB_PER_H,
        "worst_growth_mb_per_h": max(
            (g for p in procs.values() if (g := p["growth_after_warmup_mb_per_h"]) is not None), default=math.nan
        ),
        "processes": procs,
        "windows": windows,
        "summary": {k: summary.get(k) for k in ("mota", "idf1", "id_switches", "recall", "recording_lost", "restarts")},
        "out": str(out),
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="benchmarks.bench_soak", description=__doc__.split("\n\n")[0])
    p.add_argument("--duration", type=float, default=3600.0, help="seconds of demo (default an hour)")
    p.add_argument("--sample-s", type=float, default=30.0, help="RSS sampling period")
    p.add_argument("--window-s", type=float, default=600.0, help="scoring window")
    p.add_argument("--warmup-s", type=float, default=600.0, help="growth is fitted from this many seconds on")
    p.add_argument("--seed", type=int, default=7, help="world seed (panostereo demo --seed)")
    p.add_argument("--threshold", type=float, default=0.5, help="evaluation match distance (m)")
    p.add_argument("--out", default=None, help="output folder (default runs/soak-<time>)")
    p.add_argument("--json", default=None, help="also write the JSON here")
    args = p.parse_args(argv)
    if not args.duration > 0 or not args.sample_s > 0 or not args.window_s > 0:
        p.error("--duration, --sample-s and --window-s must be > 0")
    res = run(args)
    text = json.dumps(res, indent=1)
    if args.json:
        Path(args.json).write_text(text + "\n")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
