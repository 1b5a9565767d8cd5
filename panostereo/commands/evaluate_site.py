"""``panostereo evaluate-site SITE [--config manager.toml] [--json]``: score a dataset site in dataset time.

Plays the site's detection files through the manager's own ``Fusion`` with no wall clock and no zenoh
(:mod:`panostereo.datasets.play`): deterministic, and seconds where the live network takes the dataset's
duration. Prints CLEAR-MOT (MOTA, MOTP, false positives, misses, ID switches), IDF1, and the mean and p90 error,
at 0.5 m and 1.0 m (``--threshold`` to choose), scored on every ground-truth frame from the first, and how often
each camera disagreed with the others over the run (the live manager's calibration check).
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from common.cli import positive
from panostereo.datasets.play import evaluate_site

__all__ = ["configure", "run"]


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("site", help="a dataset site file (made by `panostereo import`)")
    parser.add_argument("--config", default=None, metavar="MANAGER.toml", help="manager config (default: the site's)")
    parser.add_argument(
        "--threshold", type=positive, nargs="+", default=[0.5, 1.0], metavar="M", help="match distances (m)"
    )
    parser.add_argument(
        "--publish-lag-s",
        type=float,
        default=None,
        metavar="S",
        help="publish each instant's tracks S seconds late, once their ids have settled ([manager] publish_lag_s; "
        "the live figures are printed beside)",
    )
    parser.add_argument("--json", action="store_true", help="print the report as JSON")
    parser.add_argument("--tracks-csv", default=None, metavar="FILE", help="also write the tracks (frame,id,x_m,y_m)")
    parser.add_argument(
        "--plot",
        default=None,
        metavar="PNG",
        help="also draw the run: top view beside the ground truth, and who was followed by which track over time",
    )


def run(args: argparse.Namespace) -> int:
    report, played = evaluate_site(
        args.site, manager_config=args.config, thresholds_m=args.threshold, publish_lag_s=args.publish_lag_s
    )
    for warning in report.get("warnings", []):
        print(f"WARNING: {warning}", file=sys.stderr)
    if args.tracks_csv:
        from user_agent.report import write_tracks_csv

        rows = write_tracks_csv(args.tracks_csv, played.hypotheses)
        report["tracks_csv"] = {"path": args.tracks_csv, "rows": rows}
    if args.plot:
        from panostereo.datasets.play import plot_site

        report["plot"] = str(plot_site(args.site, played, args.plot, threshold_m=args.threshold[0]))
    if args.json:
        print(json.dumps(report, indent=2))
        return 0
    print(
        f"{report['site']}: {len(report['cameras'])} cameras, {report['frames']} frames at {report['fps']:g} fps, "
        f"played in {report['seconds']['play']:.2f} s ({report['tick_ms_mean']} ms per tick)"
    )
    where = report["scored_area"]
    lag = f", published {report['publish_lag_s']:g} s late" if report["publish_lag_s"] else ""
    print(f"scored {'where the ground truth annotates people' if where == 'ground_truth' else 'everywhere'}{lag}:")
    _table(report["scores"])
    if where == "ground_truth":
        print("scored everywhere (tracks outside the annotated area count as false positives):")
        _table(report["scores_everywhere"])
    if "live" in report:
        print("live (published at once):")
        _table(report["live"]["scores"])
    for name, recall in report.get("shared_detector_recall", {}).items():
        print(f"multi-view detector {name!r}: recall learnt {recall:.3f}")
    if report.get("tracks_ended_inside") is not None:
        print(f"tracks that ended inside the area, away from its exits: {report['tracks_ended_inside']}")
    _agreement(report.get("agreement", []))
    if "plot" in report:
        print(f"plot: {report['plot']}")
    return 0


def _agreement(rows: list[dict[str, Any]]) -> None:
    """The cameras' agreement check over the run, as the live manager reports it (ManagerStatus.agreement)."""
    if not rows:
        return
    off = [r for r in rows if r["disagreed_share"] > 0]
    if not off:
        lo, hi = min(r["residual_m"] for r in rows), max(r["residual_m"] for r in rows)
        print(f"calibration check: every camera agrees with the others (median residuals {lo:.2f}-{hi:.2f} m)")
        return
    said = ", ".join(f"{r['sensor_id']} at {100 * r['disagreed_share']:.0f} % (median residual {r['residual_m']:.2f} m)"
                     for r in off)  # fmt: skip
    print(f"calibration check: cameras whose blobs disagreed with the others' people, share of instants: {said}")
    print("  a camera that disagrees often is likely off its calibration: `panostereo calib refine` (README: "
          "Calibrating a site) finds its pose from these people")  # fmt: skip


def _table(scores: list[dict[str, float]]) -> None:
    head = ("threshold", "MOTA", "IDF1", "IDsw", "ids/pp", "frag", "FP", "miss", "MOTP m", "p90 m")
    print("  {:>9} {:>7} {:>7} {:>5} {:>6} {:>5} {:>6} {:>6} {:>7} {:>7}".format(*head))
    for s in scores:
        print(
            f"  {s['threshold_m']:>8g}m {_f(s['mota'])} {_f(s['idf1'])} {s['id_switches']:>5} "
            f"{s['ids_per_person'] or 0:>6.2f} {s['fragmentations']:>5} {s['false_positives']:>6} {s['misses']:>6} "
            f"{_f(s['motp_m'])} {_f(s['p90_error_m'])}"
        )


def _f(v: float | None) -> str:
    return f"{v:7.3f}" if v is not None else f"{'-':>7}"
