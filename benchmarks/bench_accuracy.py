"""Localisation and tracking accuracy of the resource manager (issue 6, item 10).

Usage::

    python -m benchmarks.bench_accuracy [--parts synthetic,network,wildtrack] [--duration 60]
        [--wildtrack /path/to/wildtrack] [--wildtrack-frames 200] [--out DIR]

Three parts, each reported separately in one JSON object:

* ``synthetic``: the pure :class:`resource_manager.fusion.Fusion` fed projected features (head bearings
  with 1 px = 0.2 deg Gaussian noise, sightings with 1 px boundary noise, occlusion; the harness of
  tests/unit/resource_manager/synth.py). Not pixels: this isolates the manager's own accuracy.
* ``network``: the real multi-process network, ``panostereo demo`` on the simulated sites (rendered pixels
  -> sensor nodes -> manager -> scored by the agent's evaluator): ``paper1`` (tripod + robot by mutual
  calibration, 1 person), ``paper1`` with the robot's pose given to the manager (``[[pose]]``: surveyed),
  ``paper2`` (2 people), ``six`` (6 people, 4 cameras).
* ``wildtrack``: the real Wildtrack dataset (ground-truth boxes as detections through detection-file sensor
  nodes), pairs chosen by the error model against a random pair (``[match] pair_choice = "random"``).

Issue targets: two cameras, 1 person: mean error <= 5 cm surveyed, <= 10 cm mutual calibration; 2 people
<= 10 cm; 6 people x 4 cameras MOTA >= 0.97, IDF1 >= 0.95; Wildtrack: error-model pairs >= 2.5x better
than random pairs in mean error.
"""

from __future__ import annotations

import argparse
import json
import math
import re
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parent.parent
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from tests.support import free_port  # noqa: E402

PX = math.radians(0.2)


# -- synthetic features through the pure fusion ----------------------------------------------------
def synthetic(duration_s: float) -> dict[str, Any]:
    from tests.unit.resource_manager.scenario import make_config, run_scenario
    from tests.unit.resource_manager.synth import Cam, Person, RandomWalk, rectangle_path

    def one(t: float) -> list[Person]:
        return [Person(*rectangle_path(t, (1.0, 1.5, 4.0, 5.0), 0.8), 1.75)]

    def two(t: float) -> list[Person]:
        a = rectangle_path(t, (1.0, 1.5, 4.0, 5.0), 0.7)
        b = rectangle_path(t, (1.0, 1.5, 4.0, 5.0), 0.7, phase=0.5)
        return [Person(*a, 1.8), Person(*b, 1.6)]

    def row(run: Any) -> dict[str, Any]:
        return {
            "mean_error_m": round(run.mean_error_m, 4),
            "mota": round(run.mota["mota"], 4),
            "id_switches": run.mota["idsw"],
            "ids": len(run.ids),
        }

    out: dict[str, Any] = {}
    surveyed = [Cam("p1", 0.5, 0.5, sigma_rad=PX), Cam("p2", 3.5, 0.5, yaw=0.7, sigma_rad=PX)]
    mutual = [
        Cam("p1", 0.5, 0.5, sigma_rad=PX),
        Cam("p2", 3.5, 0.5, yaw=0.7, sigma_rad=PX, mobile=True, surveyed=False),
    ]
    out["two_cameras_1_person_surveyed"] = row(run_scenario(surveyed, one, duration_s=duration_s, seed=4))
    out["two_cameras_1_person_mutual"] = row(run_scenario(mutual, one, duration_s=duration_s, seed=4))
    out["two_cameras_2_people"] = row(
        run_scenario([Cam("p1", 0.5, 0.5), Cam("p2", 4.5, 0.5)], two, duration_s=duration_s, seed=2)
    )
    cams4 = [Cam("p1", 0.2, 0.2), Cam("p2", 7.8, 0.2), Cam("p3", 7.8, 5.8), Cam("p4", 0.2, 5.8)]
    for matcher in ("greedy", "global"):
        runs = [
            run_scenario(
                cams4,
                RandomWalk(6, (0.0, 0.0, 8.0, 6.0), seed=s).at,
                duration_s=duration_s,
                seed=s,
                config=make_config(matcher=matcher),
            )
            for s in (1, 2, 3)
        ]
        out[f"four_cameras_6_people_{matcher}"] = {
            "mota_per_seed": [round(r.mota["mota"], 4) for r in runs],
            "mean_error_m": round(sum(r.mean_error_m for r in runs) / len(runs), 4),
        }
    return out


# -- the real network ---------------------------------------------------------------------------------
def _abs_site(site: Path, out: Path, manager_cfg: Path | None) -> Path:
    """A copy of ``site`` with absolute process config paths, the manager's replaced by ``manager_cfg``."""
    text = site.read_text()
    base = site.resolve().parent

    def fix(m: re.Match[str]) -> str:
        return f'config = "{(base / m.group(1)).resolve()}"'

    text = re.sub(r'^config = "([^"]+)"', fix, text, flags=re.M)
    text = re.sub(
        r'^ground_truth = "([^"]+)"', lambda m: f'ground_truth = "{(base / m.group(1)).resolve()}"', text, flags=re.M
    )
    if manager_cfg is not None:
        text = re.sub(
            r'(command = "manager"\s*\nconfig = )"[^"]+"', lambda m: f'{m.group(1)}"{manager_cfg}"', text, flags=re.M
        )
    dest = out / f"{site.stem}-{manager_cfg.stem if manager_cfg else 'bench'}.toml"
    dest.write_text(text)
    return dest


def _manager_variant(site: Path, out: Path, extra: str, name: str) -> Path:
    m = re.search(r'command = "manager"\s*\nconfig = "([^"]+)"', site.read_text())
    if m is None:
        raise SystemExit(f"{site}: no manager process")
    src = (site.resolve().parent / m.group(1)).resolve()
    text = src.read_text()
    for table, line in re.findall(r"^\[(\w+)\]\n(.*)$", extra, flags=re.M):
        if f"[{table}]" in text:
            text = text.replace(f"[{table}]", f"[{table}]\n{line}", 1)
            extra = extra.replace(f"[{table}]\n{line}\n", "")
    dest = out / f"{name}-manager.toml"
    dest.write_text(text + "\n" + extra)
    return dest


def demo(site: Path, out: Path, duration_s: float, name: str) -> dict[str, Any]:
    run_dir = out / name
    cmd = [
        sys.executable,
        "-m",
        "panostereo",
        "demo",
        "--site",
        str(site),
        "--out",
        str(run_dir),
        "--listen",
        f"tcp/127.0.0.1:{free_port()}",
        "--no-view",
    ]
    if duration_s > 0:
        cmd += ["--duration", str(duration_s)]
    proc = subprocess.run(
        cmd, capture_output=True, text=True, timeout=max(duration_s, 120) + 600, cwd=REPO, check=False
    )
    summary = run_dir / "summary.json"
    if proc.returncode != 0 or not summary.exists():
        return {"error": (proc.stderr or proc.stdout)[-800:], "returncode": proc.returncode}
    s = json.loads(summary.read_text())
    keys = ("cameras", "people", "frames", "mota", "idf1", "id_switches", "mean_error_m", "p90_error_m", "recall")
    return {k: s.get(k) for k in keys} | {"summary": str(summary)}


def network(out: Path, duration_s: float) -> dict[str, Any]:
    sites = REPO / "deploy" / "sites"
    res: dict[str, Any] = {}
    p1 = sites / "paper1.toml"
    res["paper1_mutual"] = demo(_abs_site(p1, out, None), out, duration_s, "paper1_mutual")
    # The robot's true pose (deploy/sites/paper1.toml) given to the manager: both poses surveyed.
    survey = _manager_variant(
        p1, out, '[[pose]]\nid = "robot"\nx_m = 2.0\ny_m = 4.2\nz_m = 1.1\nyaw_deg = 250.0\n', "p1s"
    )
    res["paper1_surveyed"] = demo(_abs_site(p1, out, survey), out, duration_s, "paper1_surveyed")
    res["paper2_two_people"] = demo(_abs_site(sites / "paper2.toml", out, None), out, duration_s, "paper2")
    res["six_people_four_cameras"] = demo(_abs_site(sites / "six.toml", out, None), out, duration_s, "six")
    return res


def wildtrack(out: Path, dataset: Path, frames: int) -> dict[str, Any]:
    from panostereo.datasets.wildtrack import import_wildtrack

    imp = import_wildtrack(dataset, out / "wildtrack", max_frames=frames)
    site = Path(imp.site)
    res: dict[str, Any] = {}
    for choice in ("error_model", "random"):
        cfg = _manager_variant(site, out, f'[match]\npair_choice = "{choice}"\n', f"wt-{choice}")
        res[choice] = demo(_abs_site(site, out, cfg), out, 0.0, f"wildtrack-{choice}")
    em, rnd = res["error_model"].get("mean_error_m"), res["random"].get("mean_error_m")
    if isinstance(em, float) and isinstance(rnd, float) and em > 0:
        res["random_over_error_model"] = round(rnd / em, 3)
    return res


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="bench_accuracy", description=__doc__.splitlines()[0])
    p.add_argument("--parts", default="synthetic,network", help="comma list of synthetic,network,wildtrack")
    p.add_argument("--duration", type=float, default=60.0, help="seconds per network run")
    p.add_argument("--synthetic-duration", type=float, default=30.0)
    p.add_argument("--wildtrack", default="", help="Wildtrack dataset folder (annotations_positions/, calibrations/)")
    p.add_argument("--wildtrack-frames", type=int, default=200)
    p.add_argument("--out", default="", help="output folder (default: a temporary one)")
    args = p.parse_args(argv)
    parts = set(args.parts.split(","))
    out = Path(args.out or tempfile.mkdtemp(prefix="bench-accuracy-"))
    out.mkdir(parents=True, exist_ok=True)
    result: dict[str, Any] = {"benchmark": "accuracy", "out": str(out)}
    if "synthetic" in parts:
        result["synthetic"] = synthetic(args.synthetic_duration)
    if "network" in parts:
        result["network"] = network(out, args.duration)
    if "wildtrack" in parts:
        if not args.wildtrack:
            result["wildtrack"] = {"error": "--wildtrack DATASET_DIR is required for this part"}
        else:
            result["wildtrack"] = wildtrack(out, Path(args.wildtrack), args.wildtrack_frames)
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
