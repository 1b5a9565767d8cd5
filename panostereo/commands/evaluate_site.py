"""``panostereo evaluate-site SITE [--config manager.toml] [--json]``: score a dataset site in dataset time.

Plays the site's detection files through the manager's own ``Fusion`` with no wall clock and no zenoh
(:mod:`panostereo.datasets.play`): deterministic, and seconds where the live network takes the dataset's
duration. Prints CLEAR-MOT (MOTA, MOTP, false positives, misses, ID switches), IDF1, and the mean and p90 error,
at 0.5 m and 1.0 m (``--threshold`` to choose), scored on every ground-truth frame from the first.
"""

from __future__ import annotations

import argparse
import json

from panostereo.datasets.play import evaluate_site

__all__ = ["configure", "run"]


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("site", help="a dataset site file (made by `panostereo import`)")
    parser.add_argument("--config", default=None, metavar="MANAGER.toml", help="manager config (default: the site's)")
    parser.add_argument(
        "--threshold", type=float, nargs="+", default=[0.5, 1.0], metavar="M", help="match distances (m)"
    )
    parser.add_argument("--json", action="store_true", help="print the report as JSON")
    parser.add_argument("--tracks-csv", default=None, metavar="FILE", help="also write the tracks (frame,id,x_m,y_m)")


def run(args: argparse.Namespace) -> int:
    report, played = evaluate_site(args.site, manager_config=args.config, thresholds_m=args.threshold)
    if args.tracks_csv:
        from user_agent.report import write_tracks_csv

        rows = write_tracks_csv(args.tracks_csv, played.hypotheses)
        report["tracks_csv"] = {"path": args.tracks_csv, "rows": rows}
    if args.json:
        print(json.dumps(report, indent=2))
        return 0
    print(
        f"{report['site']}: {len(report['cameras'])} cameras, {report['frames']} frames at {report['fps']:g} fps, "
        f"played in {report['seconds']['play']:.2f} s ({report['tick_ms_mean']} ms per tick)"
    )
    where = report["scored_area"]
    print(f"scored {'where the ground truth annotates people' if where == 'ground_truth' else 'everywhere'}:")
    _table(report["scores"])
    if where == "ground_truth":
        print("scored everywhere (tracks outside the annotated area count as false positives):")
        _table(report["scores_everywhere"])
    return 0


def _table(scores: list[dict[str, float]]) -> None:
    head = ("threshold", "MOTA", "IDF1", "MOTP m", "FP", "miss", "IDsw", "mean m", "p90 m")
    print("  {:>9} {:>7} {:>7} {:>7} {:>6} {:>6} {:>5} {:>7} {:>7}".format(*head))
    for s in scores:
        print(
            f"  {s['threshold_m']:>8g}m {_f(s['mota'])} {_f(s['idf1'])} {_f(s['motp_m'])} {s['false_positives']:>6} "
            f"{s['misses']:>6} {s['id_switches']:>5} {_f(s['mean_error_m'])} {_f(s['p90_error_m'])}"
        )


def _f(v: float | None) -> str:
    return f"{v:7.3f}" if v is not None else f"{'-':>7}"
