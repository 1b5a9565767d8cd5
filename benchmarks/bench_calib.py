"""Calibration from people walking (``panostereo calib refine``) on the development sets: pose error and tracking.

Usage::

    python -m benchmarks.bench_calib [--datasets ../shared/datasets] [--sets wildtrack,pets,room] [--seeds 5]
                                     [--first-seed 1] [--cases 0.5:5,1.5:15] [--out DIR]

Per set: the official site is imported; then, per case (a shift in metres and a turn in degrees) and seed, every
camera but the first (the fixed one, ``--fix``) is moved by the shift in a random direction and turned by the
turn about a random axis, and the perturbed site is refined by ``panostereo calib refine`` in a child process
(its CPU time and peak memory measured). Printed: each camera's pose error against the official calibration
(refined and perturbed), and tracking (``evaluate-site``: MOTA and IDF1 at 0.5 m and 1.0 m) with the official,
the perturbed and the refined calibration side by side. PETS 2009 also refines from the official calibration
itself (case 0:0): its views disagree with each other by decimetres. ``room`` is a simulated room (four corner
cameras, 15 people, a detector's cuts, misses and clutter: :mod:`sim.detector`), written into ``--out``, whose
calibration is exact. The ground truth is read only by the scoring.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

REPO = Path(__file__).resolve().parent.parent
SETS = ("wildtrack", "pets", "room")
EVERY_CASE = ("wildtrack", "room")
"""Sets refined from every case (an exact or trusted calibration to be found again); PETS from the first only."""
ROOM_PEOPLE = 15
ROOM_SEED = 2
"""The simulated room: four corner cameras over 15 people who hide each other (:mod:`sim.detector`), the kind
of real room the project is measured on without its data here."""
THRESHOLDS_M = (0.5, 1.0)


def add_set_arguments(p: argparse.ArgumentParser) -> None:
    """``--datasets``, ``--sets`` (of ``SETS``) and ``--out``: what a benchmark over the development sets reads and
    where it writes their sites."""
    p.add_argument("--datasets", default=str(REPO.parent / "shared" / "datasets"), help="folder of the datasets")
    p.add_argument("--sets", default=",".join(SETS), help=f"comma-separated, of {', '.join(SETS)}")
    p.add_argument("--out", default=None, metavar="DIR", help="where the sites go (default: a temporary folder)")


def chosen_sets(p: argparse.ArgumentParser, sets: str) -> list[str]:
    """The ``--sets`` value as names, each one of ``SETS`` (else the parser's error)."""
    names = sets.split(",")
    for name in names:
        if name not in SETS:
            p.error(f"--sets: unknown set {name!r} (choose from {', '.join(SETS)})")
    return names


def import_set(name: str, datasets: Path, out: Path) -> Path:
    """The development set ``name`` (of ``SETS``) as a site under ``out`` (the room: written there first)."""
    from panostereo.datasets.mot import import_mot
    from panostereo.datasets.wildtrack import import_wildtrack

    if name == "wildtrack":
        return import_wildtrack(datasets / "wildtrack", out).site
    if name == "room":
        from common.area import rectangle
        from sim.detector import write_room_dataset

        data = write_room_dataset(out.parent / "data", people=ROOM_PEOPLE, fps=4.0, duration_s=90.0, seed=ROOM_SEED)
        return import_mot(data, out, fps=4.0, area=rectangle(0.0, 0.0, 8.0, 6.0)).site
    return import_mot(datasets / "pets2009_s2l1", out, fps=7.0, min_confidence=0.5).site


def _tracking(site: Path) -> dict[str, float]:
    from panostereo.datasets.play import evaluate_site

    report, _ = evaluate_site(site, thresholds_m=THRESHOLDS_M)
    out: dict[str, float] = {}
    for t, s in zip(THRESHOLDS_M, report["scores"], strict=True):
        out[f"mota_{t:g}m"] = round(float(s["mota"]), 4)
        out[f"idf1_{t:g}m"] = round(float(s["idf1"]), 4)
    return out


def site_cameras(site: Path) -> tuple[list[Any], dict[str, Any]]:
    """A site's cameras as ``calib refine`` reads them, and each one's camera model (to write a moved site)."""
    from common.site import load_site
    from panostereo.calib.observe import from_site

    cams, _ = from_site(load_site(site), frames=1)
    return cams, {c.sensor_id: c.info.model for c in cams}


def _perturbed(official: Path, out: Path, shift_m: float, turn_rad: float, seed: int, fixed: str) -> dict[str, Any]:
    from common.site import load_site
    from panostereo.calib.site_out import write_refined_site

    cams, models = site_cameras(official)
    rng = np.random.default_rng(seed)
    poses = {}
    for c in cams:
        d, a = rng.normal(size=3), rng.normal(size=3)
        if c.sensor_id != fixed:
            poses[c.sensor_id] = c.pose.turned_moved(turn_rad * a / np.linalg.norm(a), shift_m * d / np.linalg.norm(d))
    return {"site": write_refined_site(load_site(official), poses, models, out), "poses": poses}


def _refine(site: Path, out: Path, fixed: str) -> dict[str, Any]:
    """``panostereo calib refine`` in a child process: its report, CPU seconds and peak memory."""
    cmd = [sys.executable, "-m", "panostereo", "calib", "--log-level", "WARNING", "refine", str(site)]
    cmd += ["--out", str(out), "--fix", fixed, "--json"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, cwd=REPO)
    assert proc.stdout is not None
    text = proc.stdout.read()
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        raise RuntimeError(f"calib refine failed ({proc.returncode}): {' '.join(cmd)}")
    report = json.loads(text)
    report["child_cpu_s"] = round(usage.ru_utime + usage.ru_stime, 2)
    report["child_peak_mib"] = round(usage.ru_maxrss / 1024, 1)
    return report


def _pose_errors(official: Path, site: Path) -> dict[str, list[float]]:
    from panostereo.calib.poses import pose_change

    truth, _ = site_cameras(official)
    got = {c.sensor_id: c.pose for c in site_cameras(site)[0]}
    out = {}
    for c in truth:
        moved, turned = pose_change(c.pose, got[c.sensor_id])
        out[c.sensor_id] = [round(moved, 3), round(math.degrees(turned), 3)]
    return out


def run_set(name: str, datasets: Path, work: Path, seeds: range, cases: list[tuple[float, float]]) -> dict[str, Any]:
    official = import_set(name, datasets, work / name / "official")
    cams, _ = site_cameras(official)
    fixed = cams[0].sensor_id
    result: dict[str, Any] = {"fixed": fixed, "official": _tracking(official), "cases": []}
    runs = [(0.0, 0.0, 0)] if name == "pets" and seeds.start == 1 else []
    runs += [(shift, turn, seed) for shift, turn in cases for seed in seeds]
    for shift, turn, seed in runs:
        tag = f"s{shift:g}_t{turn:g}_seed{seed}"
        sys.stderr.write(f"{name} {tag} ...\n")
        if shift or turn:
            start = _perturbed(official, work / name / f"{tag}_start", shift, math.radians(turn), seed, fixed)["site"]
        else:
            start = official
        began = time.perf_counter()
        report = _refine(start, work / name / f"{tag}_refined", fixed)
        refined = Path(report["site"])
        errors = _pose_errors(official, refined)
        free = [e for cid, e in errors.items() if cid != fixed]
        case = {
            "shift_m": shift,
            "turn_deg": turn,
            "seed": seed,
            "refine_wall_s": round(time.perf_counter() - began, 1),
            "refine_cpu_s": report["child_cpu_s"],
            "refine_peak_mib": report["child_peak_mib"],
            "max_error_m": max(e[0] for e in free),
            "max_error_deg": max(e[1] for e in free),
            "pose_error": errors,
            "undetermined": [c["sensor_id"] for c in report["cameras"] if c["status"] == "undetermined"],
            "perturbed": _tracking(start) if start != official else result["official"],
            "refined": _tracking(refined),
        }
        result["cases"].append(case)
    return result


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="bench_calib", description=__doc__.splitlines()[0])
    add_set_arguments(p)
    p.add_argument("--seeds", type=int, default=5, help="seeds per case")
    p.add_argument("--first-seed", type=int, default=1, help="the first seed (seeds run from it)")
    p.add_argument("--cases", default="0.5:5,1.5:15", help="SHIFT_M:TURN_DEG,... (PETS: the first)")
    args = p.parse_args(argv)
    cases = [(float(a), float(b)) for a, b in (c.split(":") for c in args.cases.split(","))]
    datasets = Path(args.datasets)
    out: dict[str, Any] = {}
    with tempfile.TemporaryDirectory(prefix="bench_calib_") as tmp:
        work = Path(args.out) if args.out else Path(tmp)
        for name in chosen_sets(p, args.sets):
            seeds = range(args.first_seed, args.first_seed + args.seeds)
            out[name] = run_set(name, datasets, work, seeds, cases if name in EVERY_CASE else cases[:1])
    sys.stdout.write(json.dumps(out, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
