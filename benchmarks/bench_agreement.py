"""The live check that each camera still agrees with the others (``ManagerStatus.agreement``) on the development
sets: does it name a camera moved since its calibration, and only that one?

Usage::

    python -m benchmarks.bench_agreement [--datasets ../shared/datasets] [--sets wildtrack,pets,room]
                                         [--shift-m 0.5] [--turn-deg 5] [--axis vertical|random] [--seed 1]
                                         [--out DIR]

Per set (Wildtrack's ground-truth boxes, PETS 2009's detections, the simulated room of ``bench_calib``), played in
dataset time through the manager's Fusion with the manager's check (:mod:`resource_manager.poses.agreement`) fed
every fused instant, as the live manager feeds it:

* with the official calibration: the share of instants (after the check's first window) at which each camera is
  reported as disagreeing (each one a false alarm);
* then with one camera at a time whose calibration is moved by ``--shift-m`` in a random horizontal direction and
  turned by ``--turn-deg`` about the vertical (``--axis random``: about a random axis) (its pictures no longer fit
  it: a camera bumped before the manager started, ``moved``): the share of instants at which the moved camera is
  reported (a detection) and the largest share of any other camera (a false alarm), with the moved camera's
  residual at the end;
* and the same move given to the manager half-way through (a camera bumped while it ran, ``bumped``: its own
  residual in place was learned first): the share of instants from a window after the bump on at which it is
  reported, the largest share of any other camera then, and of any camera before the bump.

Nothing of the ground truth reaches the check.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

REPO = Path(__file__).resolve().parent.parent
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from benchmarks.bench_calib import add_set_arguments, chosen_sets, import_set, site_cameras  # noqa: E402
from common.site import load_site  # noqa: E402
from panostereo.calib.site_out import write_refined_site  # noqa: E402
from panostereo.datasets.play import (  # noqa: E402
    AgreementTally,
    DatasetCamera,
    load_cameras,
    play,
    site_manager_config,
)
from resource_manager.config import ManagerConfig  # noqa: E402
from resource_manager.poses.agreement import AgreementParams  # noqa: E402


@dataclass(frozen=True, slots=True)
class Played:
    """A site as it is played: its manager config and its cameras' frames (read once, played as often as needed)."""

    config: ManagerConfig
    cameras: list[DatasetCamera]

    @classmethod
    def of(cls, site_path: Path) -> Played:
        site = load_site(site_path)
        return cls(site_manager_config(site, None), load_cameras(site))


def flagged(site: Played, bumped: DatasetCamera | None = None) -> dict[str, Any]:
    """Play a site with the check fed every instant. Per camera, the share of instants (after the first window) at
    which it disagreed (``flagged``), and its residual and own residual in place at the end.

    ``bumped``: one camera as a moved calibration sees it, whose frames and SensorInfo the manager is given from
    half-way through on: the camera was moved while the manager ran. ``flagged`` then counts the first half only
    (false alarms) and ``flagged_after`` the instants from a window after the bump on."""
    cameras = site.cameras
    stamps = [f.stamp_ns for cam in cameras for f in cam.features]
    bump_ns = (min(stamps) + max(stamps)) // 2 if bumped is not None else None
    infos_at = []
    if bumped is not None and bump_ns is not None:
        # From the bump on, the camera's blobs are those of the moved calibration (a node's blobs are worked out
        # with its own), and the manager is told its new SensorInfo.
        cameras = [
            c
            if c.sensor_id != bumped.sensor_id
            else replace(
                c,
                features=[f for f in c.features if f.stamp_ns < bump_ns]
                + [f for f in bumped.features if f.stamp_ns >= bump_ns],
            )
            for c in cameras
        ]
        infos_at = [(bump_ns, bumped.info)]
    window_ns = int(AgreementParams().window_s * 1e9)

    def bucket(t_ns: int) -> str | None:
        if bump_ns is None or t_ns < bump_ns:
            return "before"
        return "after" if t_ns >= bump_ns + window_ns else None

    tally = AgreementTally(bucket=bucket)
    play(cameras, site.config, on_tick=tally.on_tick, infos_at=infos_at)
    report = tally.check.report()
    return {
        "flagged": tally.shares("before"),
        "flagged_after": tally.shares("after"),
        "residual_m": {a.sensor_id: round(a.residual_m, 3) for a in report},
        "settled_m": {a.sensor_id: None if a.settled_m is None else round(a.settled_m, 3) for a in report},
    }


def moved(
    official: Path, out: Path, camera: str, shift_m: float, turn_rad: float, seed: int, *, axis: str = "vertical"
) -> Path:
    """The site with ``camera``'s calibration moved horizontally and turned about the vertical (``axis``:
    ``vertical``, a camera knocked round on its mount) or about a random axis (``random``, a tilt as likely as a
    turn): its pictures no longer fit its calibration, as those of a camera bumped since it was calibrated."""
    cams, models = site_cameras(official)
    cam = next(c for c in cams if c.sensor_id == camera)
    rng = np.random.default_rng(seed)
    d, a = rng.normal(size=3), rng.normal(size=3)
    d[2] = 0.0
    if axis == "vertical":
        a = np.array([0.0, 0.0, 1.0 if a[2] >= 0 else -1.0])
    pose = cam.pose.turned_moved(turn_rad * a / np.linalg.norm(a), shift_m * d / np.linalg.norm(d))
    return write_refined_site(load_site(official), {camera: pose}, models, out)


def run_set(
    name: str, datasets: Path, work: Path, shift_m: float, turn_rad: float, seed: int, axis: str
) -> dict[str, Any]:
    official = import_set(name, datasets, work / name / "official")
    played = Played.of(official)
    in_place = flagged(played)
    out: dict[str, Any] = {"in_place": in_place, "moved": {}, "bumped": {}}
    for k, cam in enumerate(sorted(in_place["flagged"])):
        sys.stderr.write(f"{name}: {cam} moved ...\n")
        moved_site = Played.of(
            moved(official, work / name / f"moved_{cam}", cam, shift_m, turn_rad, seed + k, axis=axis)
        )
        run = flagged(moved_site)
        out["moved"][cam] = {
            "flagged": run["flagged"].get(cam, 0.0),
            "others_flagged_max": max((v for sid, v in run["flagged"].items() if sid != cam), default=0.0),
            "residual_m": run["residual_m"].get(cam),
        }
        run = flagged(played, bumped=next(c for c in moved_site.cameras if c.sensor_id == cam))
        out["bumped"][cam] = {
            "flagged_before": max(run["flagged"].values(), default=0.0),
            "flagged": run["flagged_after"].get(cam, 0.0),
            "others_flagged_max": max((v for sid, v in run["flagged_after"].items() if sid != cam), default=0.0),
            "residual_m": run["residual_m"].get(cam),
            "settled_m": run["settled_m"].get(cam),
        }
    moved_rows, bumped_rows = out["moved"].values(), out["bumped"].values()
    out["summary"] = {
        "false_alarm_max_in_place": max(in_place["flagged"].values(), default=0.0),
        "moved_cameras": len(out["moved"]),
        "moved_flagged_most_of_the_time": sum(1 for r in moved_rows if r["flagged"] > 0.5),
        "false_alarm_max_when_one_moved": max((r["others_flagged_max"] for r in moved_rows), default=0.0),
        "bumped_flagged_most_of_the_time": sum(1 for r in bumped_rows if r["flagged"] > 0.5),
        "false_alarm_max_when_one_bumped": max((r["others_flagged_max"] for r in bumped_rows), default=0.0),
    }
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="bench_agreement", description=__doc__.splitlines()[0])
    add_set_arguments(p)
    p.add_argument("--shift-m", type=float, default=0.5, help="how far the moved camera moves (m)")
    p.add_argument("--turn-deg", type=float, default=5.0, help="how far it turns (degrees)")
    p.add_argument("--axis", choices=("vertical", "random"), default="vertical", help="what the turn is about")
    p.add_argument("--seed", type=int, default=1, help="the first camera's seed (the next ones count on)")
    args = p.parse_args(argv)
    out: dict[str, Any] = {"shift_m": args.shift_m, "turn_deg": args.turn_deg, "axis": args.axis}
    with tempfile.TemporaryDirectory(prefix="bench_agreement_") as tmp:
        work = Path(args.out) if args.out else Path(tmp)
        turn = math.radians(args.turn_deg)
        for name in chosen_sets(p, args.sets):
            out[name] = run_set(name, Path(args.datasets), work, args.shift_m, turn, args.seed, args.axis)
    sys.stdout.write(json.dumps(out, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
