"""Fusion tick time of the resource manager for 2-16 cameras x 1-30 people (issue 6, item 11).

Usage::

    python -m benchmarks.bench_fusion [--cameras 2,4,8,16] [--people 1,5,10,20,30] [--seconds 6] [--matcher greedy]

Synthetic features (tests/unit/resource_manager/synth.py: noisy head bearings, widths, tops, colours,
occlusion) of people walking in a 12 x 10 m room watched by panoramic cameras spread around the walls
(surveyed poses) are fed to ``Fusion.step`` as they would arrive (15 fps, 10 Hz ticks, 200 ms latency).
The tick time (``Fusion.step`` only: ingest, align, poses, pair choice, Eq. 7 matching, localisation,
tracking, births; not the feature synthesis between ticks) is the thread's CPU time (``time.thread_time``:
one core; other processes sharing the machine still slow it through shared caches and SMT, so compare runs
made under the same load; the wall time is reported beside it) after a 2 s warm-up.

Prints one JSON object: per configuration the mean/p50/p99 tick in ms, the MOTA and mean position error of
the run (the tracking result, which optimisations must leave unchanged), the goal check (16 cameras x 20
people <= 10 ms mean) and the growth: ``tick ~ cameras^a x people^b``, a and b fitted by least squares on
log(tick) over the runs with >= 2 people; the goal "no worse than cameras x people" is a <= 1 and b <= 1.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from tests.unit.resource_manager.scenario import make_config, run_scenario  # noqa: E402
from tests.unit.resource_manager.synth import Cam, RandomWalk  # noqa: E402

ROOM = (0.0, 0.0, 12.0, 10.0)


def cameras(n: int) -> list[Cam]:
    """``n`` cameras evenly spaced along the walls, 0.2 m inside."""
    x0, y0, x1, y1 = ROOM[0] + 0.2, ROOM[1] + 0.2, ROOM[2] - 0.2, ROOM[3] - 0.2
    w, h = x1 - x0, y1 - y0
    per = 2 * (w + h)
    out = []
    for k in range(n):
        s = (k + 0.5) * per / n
        if s < w:
            xy = (x0 + s, y0)
        elif s < w + h:
            xy = (x1, y0 + s - w)
        elif s < 2 * w + h:
            xy = (x1 - (s - w - h), y1)
        else:
            xy = (x0, y1 - (s - 2 * w - h))
        out.append(Cam(f"c{k:02d}", *xy))
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="bench_fusion", description=__doc__.splitlines()[0])
    p.add_argument("--cameras", default="2,4,8,16")
    p.add_argument("--people", default="1,5,10,20,30")
    p.add_argument("--seconds", type=float, default=6.0, help="simulated seconds per configuration")
    p.add_argument("--matcher", default="greedy", choices=["greedy", "global"])
    p.add_argument("--seed", type=int, default=1)
    args = p.parse_args(argv)
    cams_list = [int(v) for v in args.cameras.split(",")]
    people_list = [int(v) for v in args.people.split(",")]
    runs = []
    for nc in cams_list:
        for npl in people_list:
            walk = RandomWalk(npl, ROOM, seed=args.seed)
            run = run_scenario(
                cameras(nc),
                walk.at,
                duration_s=args.seconds,
                seed=args.seed,
                config=make_config(matcher=args.matcher, history_s=60.0),
            )
            skip = int(2.0 * 10)  # the first 2 s: births
            ms = np.asarray(run.tick_cpu_ms[skip:] or run.tick_cpu_ms)
            wall = np.asarray(run.tick_ms[skip:] or run.tick_ms)
            runs.append(
                {
                    "cameras": nc,
                    "people": npl,
                    "tick_ms_mean": round(float(ms.mean()), 3),
                    "tick_ms_p50": round(float(np.percentile(ms, 50)), 3),
                    "tick_ms_p99": round(float(np.percentile(ms, 99)), 3),
                    "wall_ms_mean": round(float(wall.mean()), 3),
                    "ticks": int(ms.size),
                    "mota": round(float(run.mota["mota"]), 4),
                    "mean_error_m": round(run.mean_error_m, 4) if math.isfinite(run.mean_error_m) else None,
                }
            )
    # growth: log(tick) = a + b log(cameras) + c log(people), over runs with >= 2 people
    fit = [r for r in runs if r["people"] >= 2]
    growth = None
    if len({r["cameras"] for r in fit}) > 1 and len({r["people"] for r in fit}) > 1:
        a = np.array([[1.0, math.log(r["cameras"]), math.log(r["people"])] for r in fit])
        y = np.array([math.log(max(r["tick_ms_mean"], 1e-3)) for r in fit])
        coef, *_ = np.linalg.lstsq(a, y, rcond=None)
        growth = {
            "model": "tick_ms ~ cameras^cameras_exponent * people^people_exponent (log-log fit, runs >= 2 people)",
            "cameras_exponent": round(float(coef[1]), 3),
            "people_exponent": round(float(coef[2]), 3),
            "goal": "both exponents <= 1 (no worse than cameras x people)",
            "goal_met": bool(coef[1] <= 1.0 and coef[2] <= 1.0),
        }
    goal = next((r for r in runs if r["cameras"] == 16 and r["people"] == 20), None)
    print(
        json.dumps(
            {
                "benchmark": "fusion_tick",
                "matcher": args.matcher,
                "seconds_per_config": args.seconds,
                "runs": runs,
                "growth": growth,
                "goal_16x20_ms": 10.0,
                "goal_16x20_met": None if goal is None else goal["tick_ms_mean"] <= 10.0,
            }
        )
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
