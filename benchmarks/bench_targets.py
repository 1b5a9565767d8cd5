"""Every target of the real-data tracker issue, measured with the default config, in one JSON table.

Usage::

    python -m benchmarks.bench_targets [--datasets ../shared/datasets] [--parts real,pairs,fusion,sims]
        [--duration 40] [--out DIR]

Parts:

* ``real``: ``evaluate-site`` (dataset time) on Wildtrack with its ground-truth boxes (all 400 frames), the same
  with 2 px box noise and 10 % of boxes dropped (the importer's options), and PETS 2009 S2.L1 with a real
  detector's boxes (conf >= 0.5, all seven views). Scored where each ground truth annotates people, and everywhere.
* ``pairs``: Wildtrack with the true association, each person-frame localised by the pair the error model ranks
  best against a random pair of the cameras that see them (:func:`benchmarks.bench_accuracy.wildtrack_pairs`).
* ``fusion``: the fusion tick for 16 cameras x 20 people and its growth (:mod:`benchmarks.bench_fusion`).
* ``sims``: the simulated sites through the real network (``panostereo demo``): the demo, six people on world
  seeds 5, 9, 21, 3 and 11, paper1 with the robot's pose surveyed and by mutual calibration, paper2.

Prints ``{"targets": [{"name", "value", "goal", "met"}, ...], "details": {...}}``; a part that cannot run (a
dataset not found) says why in ``details``.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parent.parent
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

SIX_SEEDS = (5, 9, 21, 3, 11)
PARTS = ("real", "pairs", "fusion", "sims")


def _target(name: str, value: float | None, goal: str, ok: Callable[[float], bool]) -> dict[str, Any]:
    return {"name": name, "value": value, "goal": goal, "met": None if value is None else bool(ok(value))}


def real(datasets: Path, out: Path) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    from panostereo.datasets.mot import import_mot
    from panostereo.datasets.play import evaluate_site
    from panostereo.datasets.wildtrack import import_wildtrack

    targets: list[dict[str, Any]] = []
    details: dict[str, Any] = {}
    wt, pets = datasets / "wildtrack", datasets / "pets2009_s2l1"
    if (wt / "annotations_positions").is_dir():
        clean, _ = evaluate_site(import_wildtrack(wt, out / "wildtrack").site)
        noisy, _ = evaluate_site(import_wildtrack(wt, out / "wildtrack-noisy", noise_px=2.0, drop_rate=0.1).site)
        details |= {"wildtrack": clean, "wildtrack_noise2px_drop10": noisy}
        c05, n05 = clean["scores"][0], noisy["scores"][0]
        targets += [
            _target("wildtrack MOTA @0.5 m", c05["mota"], ">= 0.93", lambda v: v >= 0.93),
            _target("wildtrack IDF1 @0.5 m", c05["idf1"], ">= 0.90", lambda v: v >= 0.90),
            _target("wildtrack 2 px noise, 10 % dropped: MOTA @0.5 m", n05["mota"], ">= 0.85", lambda v: v >= 0.85),
        ]
    else:
        details["wildtrack"] = f"not found at {wt}"
    if (pets / "detections").is_dir():
        report, _ = evaluate_site(import_mot(pets, out / "pets", fps=7.0, min_confidence=0.5).site)
        details["pets2009_s2l1"] = report
        p05, p10 = report["scores"]
        targets += [
            _target("pets2009 MOTA @1.0 m", p10["mota"], ">= 0.85", lambda v: v >= 0.85),
            _target("pets2009 IDF1 @1.0 m", p10["idf1"], ">= 0.80", lambda v: v >= 0.80),
            _target("pets2009 MOTA @0.5 m", p05["mota"], "reported", lambda v: True),
            _target("pets2009 IDF1 @0.5 m", p05["idf1"], "reported", lambda v: True),
        ]
    else:
        details["pets2009_s2l1"] = f"not found at {pets}"
    return targets, details


def pairs(datasets: Path, out: Path) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    from benchmarks.bench_accuracy import wildtrack_pairs

    wt = datasets / "wildtrack"
    if not (wt / "annotations_positions").is_dir():
        return [], {"pair_choice": f"not found at {wt}"}
    res = wildtrack_pairs(wt, out, frames=0, seed=0)
    ratio = res["random"]["mean_m"] / res["error_model"]["mean_m"]
    target = _target(
        "wildtrack: random pair / error-model pair mean error", round(ratio, 3), ">= 2.5", lambda v: v >= 2.5
    )
    return [target], {"pair_choice": res}


def fusion() -> tuple[list[dict[str, Any]], dict[str, Any]]:
    cmd = [sys.executable, "-m", "benchmarks.bench_fusion", "--cameras", "4,8,16", "--people", "5,10,20"]
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=REPO, check=False, timeout=3600)
    try:
        res = json.loads(proc.stdout.strip().splitlines()[-1])
    except (IndexError, json.JSONDecodeError):
        return [], {"fusion": {"error": proc.stderr[-800:]}}
    goal = next((r for r in res["runs"] if r["cameras"] == 16 and r["people"] == 20), {})
    growth = res.get("growth") or {}
    targets = [
        _target("fusion tick 16 cameras x 20 people (ms)", goal.get("tick_ms_mean"), "<= 10", lambda v: v <= 10.0),
        _target(
            "fusion tick growth exponents (cameras, people)",
            max(growth.get("cameras_exponent", 0.0), growth.get("people_exponent", 0.0)) if growth else None,
            "both <= 1",
            lambda v: v <= 1.0,
        ),
    ]
    return targets, {"fusion": res}


def sims(out: Path, duration_s: float) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    from benchmarks.bench_accuracy import demo, network, site_with_manager, six_seeds

    net = network(out, duration_s)
    seeds = six_seeds(out, duration_s, list(SIX_SEEDS))
    dem = demo(site_with_manager(REPO / "deploy" / "sites" / "demo.toml", out, None), out, duration_s, "demo", 7)

    def cm(row: dict[str, Any]) -> float | None:
        err = row.get("mean_error_m")
        return round(100.0 * err, 2) if isinstance(err, float) else None

    targets = [
        _target("demo MOTA", dem.get("mota"), ">= 0.97", lambda v: v >= 0.97),
        _target("six, mean over seeds 5/9/21/3/11: MOTA", seeds.get("mota_mean"), ">= 0.97", lambda v: v >= 0.97),
        _target("six, mean over seeds 5/9/21/3/11: IDF1", seeds.get("idf1_mean"), ">= 0.95", lambda v: v >= 0.95),
        _target("paper1 surveyed: mean error (cm)", cm(net["paper1_surveyed"]), "<= 5", lambda v: v <= 5.0),
        _target("paper1 mutual: mean error (cm)", cm(net["paper1_mutual"]), "<= 10", lambda v: v <= 10.0),
        _target("paper2: mean error (cm)", cm(net["paper2_two_people"]), "<= 10", lambda v: v <= 10.0),
    ]
    return targets, {"network": net, "six_seeds": seeds, "demo": dem}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="bench_targets", description=__doc__.splitlines()[0])
    p.add_argument("--datasets", default=str(REPO.parent / "shared" / "datasets"), help="folder of the datasets")
    p.add_argument("--parts", default=",".join(PARTS), help=f"comma-separated, of {', '.join(PARTS)}")
    p.add_argument("--duration", type=float, default=40.0, help="seconds of each simulated run")
    p.add_argument("--out", default=None, metavar="DIR", help="where runs and imported sites go (default: temp)")
    args = p.parse_args(argv)
    parts = [s.strip() for s in args.parts.split(",") if s.strip()]
    unknown = sorted(set(parts) - set(PARTS))
    if unknown:
        p.error(f"unknown parts {unknown}: choose from {', '.join(PARTS)}")
    datasets = Path(args.datasets)
    with tempfile.TemporaryDirectory(prefix="bench-targets-") as tmp:
        out = Path(args.out) if args.out else Path(tmp)
        out.mkdir(parents=True, exist_ok=True)
        targets: list[dict[str, Any]] = []
        details: dict[str, Any] = {}
        for part in parts:
            if part == "real":
                t, d = real(datasets, out)
            elif part == "pairs":
                t, d = pairs(datasets, out)
            elif part == "fusion":
                t, d = fusion()
            else:
                t, d = sims(out, args.duration)
            targets += t
            details |= d
    print(json.dumps({"benchmark": "targets", "targets": targets, "details": details}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
