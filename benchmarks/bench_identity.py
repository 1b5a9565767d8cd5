"""Who is who: identity and detection figures side by side on every development set, with the default config.

Usage::

    python -m benchmarks.bench_identity [--datasets ../shared/datasets] [--rooms 3] [--lag 3.0] [--out DIR]

Sets, each played in dataset time by ``evaluate-site`` (deterministic):

* Wildtrack with its ground-truth boxes (every track counted: the importer declares the annotated grid as the
  area), and with 2 px box noise and 10 % of boxes dropped;
* Wildtrack's last 40 frames with MVDeTr's detections (``wildtrack_mvdetr``);
* PETS 2009 S2.L1 with a real detector's boxes (conf >= 0.5), where its ground truth annotates people, at 1.0 m
  and 0.5 m;
* simulated rooms (:mod:`sim.detector`): four corner cameras at 4 fps, 10 and 15 people who come and go by a
  door and hide each other, a detector that misses and cuts the boxes of people others cover, ``--rooms`` world
  seeds each (imported with ``--area``, as the held-out real room is: what it measures, with no ground truth of
  ours in it, is the kind of room this project is also judged on); and the same rooms with everyone staying in
  for the whole run (``_stay``): no door traffic, each person one identity for 90 s, so what they lose is people
  who cross and crowd each other.

Per set: MOTA, IDF1, ID switches, ids per person, fragmentations, tracks that ended inside the area away from its
exits, live and published ``--lag`` seconds late (``publish_lag_s``). Prints ``{"targets": [...], "sets": {...}}``;
a set whose data is missing says so.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parent.parent
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from common.area import rectangle  # noqa: E402
from panostereo.datasets.mot import import_mot  # noqa: E402
from panostereo.datasets.play import evaluate_site  # noqa: E402
from panostereo.datasets.wildtrack import import_wildtrack  # noqa: E402
from sim.detector import write_room_dataset  # noqa: E402

MVDETR = "mvdetr"
"""``wildtrack_mvdetr``'s boxes are MVDeTr's floor detections drawn into every view (its ABOUT.md): one shared
detector."""
ROOM_M = (8.0, 6.0)
ROOM_FPS = 4.0
ROOM_S = 90.0
FIELDS = ("mota", "idf1", "id_switches", "ids_per_person", "fragmentations", "track_ids", "gt_ids")


def _row(report: dict[str, Any], key: str, threshold_m: float) -> dict[str, Any]:
    """The figures of one scoring (``key``: scores, scores_everywhere) at one threshold, live and lagged."""

    def pick(scores: list[dict[str, Any]]) -> dict[str, Any]:
        s = next(s for s in scores if s["threshold_m"] == threshold_m)
        return {f: s[f] for f in FIELDS}

    out = {"threshold_m": threshold_m, **pick(report[key]), "tracks_ended_inside": report["tracks_ended_inside"]}
    if "live" in report:
        out = {"lagged": out, "live": pick(report["live"][key]), "publish_lag_s": report["publish_lag_s"]}
    return out


def _sets(datasets: Path, work: Path, rooms: int, lag: float) -> dict[str, Any]:
    out: dict[str, Any] = {}
    wt, pets, mvdetr = datasets / "wildtrack", datasets / "pets2009_s2l1", datasets / "wildtrack_mvdetr"
    if (wt / "annotations_positions").is_dir():
        clean, _ = evaluate_site(import_wildtrack(wt, work / "wt").site, publish_lag_s=lag)
        noisy, _ = evaluate_site(
            import_wildtrack(wt, work / "wtn", noise_px=2.0, drop_rate=0.1, seed=1).site, publish_lag_s=lag
        )
        out["wildtrack"] = _row(clean, "scores_everywhere", 0.5)
        out["wildtrack_noise2px_drop10"] = _row(noisy, "scores_everywhere", 0.5)
    else:
        out["wildtrack"] = f"not found at {wt}"
    if (mvdetr / "detections").is_dir():
        site = import_mot(mvdetr, work / "mvdetr", fps=2.0, shared_detector=MVDETR).site
        report, _ = evaluate_site(site, publish_lag_s=lag)
        out["wildtrack_mvdetr"] = _row(report, "scores_everywhere", 0.5)
    if (pets / "detections").is_dir():
        report, _ = evaluate_site(import_mot(pets, work / "pets", fps=7.0, min_confidence=0.5).site, publish_lag_s=lag)
        out["pets2009_1.0m"] = _row(report, "scores", 1.0)
        out["pets2009_0.5m"] = _row(report, "scores", 0.5)
    else:
        out["pets2009"] = f"not found at {pets}"
    area = rectangle(0.0, 0.0, *ROOM_M)
    for people, come_and_go in ((10, True), (15, True), (10, False), (15, False)):
        for seed in range(1, rooms + 1):
            name = f"room{people}{'' if come_and_go else '_stay'}_seed{seed}"
            data = write_room_dataset(work / name, people=people, fps=ROOM_FPS, duration_s=ROOM_S, seed=seed,
                                      enter_leave=come_and_go)  # fmt: skip
            site = import_mot(data, work / f"{name}-site", fps=ROOM_FPS, area=area).site
            report, _ = evaluate_site(site, publish_lag_s=lag)
            out[name] = _row(report, "scores", 0.5)
    return out


def _live(row: dict[str, Any] | str) -> dict[str, Any] | None:
    if isinstance(row, str):
        return None
    return row.get("live", row)


def _targets(sets: dict[str, Any]) -> list[dict[str, Any]]:
    """The identity issue's targets on the real sets (live figures: the default config publishes at once)."""
    out: list[dict[str, Any]] = []

    def target(name: str, row: dict[str, Any] | None, field: str, goal: str, ok: bool | None) -> None:
        out.append({"name": name, "value": None if row is None else row[field], "goal": goal, "met": ok})

    wt, wtn, p1 = (_live(sets.get(k, "missing")) for k in ("wildtrack", "wildtrack_noise2px_drop10", "pets2009_1.0m"))
    if wt is not None:
        target("wildtrack MOTA @0.5 m", wt, "mota", ">= 0.93", wt["mota"] >= 0.93)
        target("wildtrack IDF1 @0.5 m", wt, "idf1", ">= 0.95", wt["idf1"] >= 0.95)
        target("wildtrack ID switches", wt, "id_switches", "<= 50", wt["id_switches"] <= 50)
        ratio = wt["track_ids"] / max(wt["gt_ids"], 1)
        out.append({"name": "wildtrack track ids / people", "value": round(ratio, 3), "goal": "<= 1.1",
                    "met": ratio <= 1.1})  # fmt: skip
    if wtn is not None:
        target("wildtrack 2 px noise, 10 % dropped: IDF1 @0.5 m", wtn, "idf1", ">= 0.90", wtn["idf1"] >= 0.90)
    if p1 is not None:
        target("pets2009 MOTA @1.0 m", p1, "mota", ">= 0.92", p1["mota"] >= 0.92)
        target("pets2009 IDF1 @1.0 m", p1, "idf1", ">= 0.90", p1["idf1"] >= 0.90)
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="bench_identity", description=__doc__.split("\n\n")[0])
    p.add_argument("--datasets", default=str(REPO.parent / "shared" / "datasets"), help="the shared datasets folder")
    p.add_argument("--rooms", type=int, default=3, help="world seeds of each simulated room (0: none)")
    p.add_argument("--lag", type=float, default=3.0, help="publish_lag_s of the lagged figures (0: live only)")
    p.add_argument("--out", default=None, metavar="DIR", help="keep the imported sites here (default: a temp dir)")
    args = p.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="bench_identity-") as tmp:
        work = Path(args.out) if args.out else Path(tmp)
        sets = _sets(Path(args.datasets), work, args.rooms, args.lag)
    rooms = {
        n: [_live(v) for k, v in sets.items() if k.startswith(f"room{n}_") and not isinstance(v, str)] for n in (10, 15)
    }
    summary = {
        f"room{n}_mean": {f: round(sum(r[f] for r in rs) / len(rs), 4) for f in ("mota", "idf1", "ids_per_person")}
        for n, rs in rooms.items()
        if rs
    }
    print(json.dumps({"targets": _targets(sets), "rooms": summary, "sets": sets}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
