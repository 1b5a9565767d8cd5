"""Where a development set's ground truth itself breaks who is who, and how many of a run's ID switches lie there.

Usage::

    python -m benchmarks.bench_ground_truth [--datasets ../shared/datasets] [--out DIR]

A ground truth is annotated by hand at a few frames a second: a person's position may jump farther than anyone walks
in one frame (a box placed late, then caught up), a person may be missing from a frame between two that have them,
and one person's id may end where a new id starts (an annotator who lost them, or a dataset that gives a new id to
whoever comes back into one camera's view, as PETS 2009's does). A tracker that follows the person through any of
these is scored as if it had swapped or split them. Per set (Wildtrack's ground-truth boxes, clean and noisy;
Wildtrack's last 40 frames with MVDeTr's detections; PETS 2009 at 1.0 m), played with the default config as
``evaluate-site`` plays it, this prints:

* the ground truth's artifacts: jumps (a step faster than ``[tracker] max_speed_mps``), one-frame gaps, and id
  handovers (an id that starts within a second of another one's end, where that person could have walked);
* the run's MOTA, IDF1 and ID switches (scored as ``evaluate-site`` scores the set first), and how many of the
  switches lie within a frame of an artifact of the person switched or of the person the old track went on with.

An id handover is only a candidate: at an area's edge one person often leaves where another comes in, so it is
not taken for one person.
"""

from __future__ import annotations

import argparse
import itertools
import json
import sys
import tempfile
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

REPO = Path(__file__).resolve().parent.parent
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from benchmarks.bench_identity import MVDETR  # noqa: E402
from common.site import load_site  # noqa: E402
from panostereo.datasets.mot import import_mot  # noqa: E402
from panostereo.datasets.play import DATASET_EPOCH_NS, evaluate_site, scored_first  # noqa: E402
from panostereo.datasets.wildtrack import import_wildtrack  # noqa: E402
from resource_manager.track.model import PERSON_RADIUS_M, TrackModel  # noqa: E402
from user_agent.groundtruth import GroundTruth, read_gt_csv  # noqa: E402
from user_agent.report import score_tracksets  # noqa: E402

HANDOVER_S = 1.0
"""An id that starts this soon after another ended, where that person could have walked, may be them."""
NEAR_FRAMES = 1
"""A switch within this many frames of an artifact is counted as lying at it."""


@dataclass
class Artifacts:
    """A ground truth's own breaks of who is who: person id -> the frames where each kind lies."""

    jumps: dict[str, set[int]] = field(default_factory=lambda: defaultdict(set))
    gaps: dict[str, set[int]] = field(default_factory=lambda: defaultdict(set))
    handovers: list[tuple[str, str]] = field(default_factory=list)
    """(id that ended, id that started) pairs."""
    handover_frames: dict[str, set[int]] = field(default_factory=lambda: defaultdict(set))

    def near(self, person: str, frame: int) -> str | None:
        """The kind of artifact of ``person`` within ``NEAR_FRAMES`` of ``frame`` (None: none)."""
        window = set(range(frame - NEAR_FRAMES, frame + NEAR_FRAMES + 1))
        for kind, where in (("jump", self.jumps), ("gap", self.gaps), ("handover", self.handover_frames)):
            if where.get(person, set()) & window:
                return kind
        return None

    def counts(self) -> dict[str, int]:
        return {
            "jumps": sum(len(f) for f in self.jumps.values()) // 2,
            "one_frame_gaps": sum(len(f) for f in self.gaps.values()),
            "id_handovers": len(self.handovers),
        }


def find_artifacts(gt: GroundTruth, fps: float, max_speed_mps: float) -> Artifacts:
    """The jumps, one-frame gaps and id handovers of ``gt`` (frames ``1 / fps`` apart)."""
    out = Artifacts()
    tracks = {pid: gt.track_of(pid) for pid in gt.person_ids}
    step_m = max_speed_mps / fps
    for pid, pts in tracks.items():
        for a, b in itertools.pairwise(pts):
            if b.frame == a.frame + 1 and float(np.hypot(b.x_m - a.x_m, b.y_m - a.y_m)) > step_m:
                out.jumps[pid] |= {a.frame, b.frame}
            elif b.frame == a.frame + 2:  # one frame missing between two
                out.gaps[pid].add(a.frame + 1)
    window = max(1, round(HANDOVER_S * fps))
    for old, po in tracks.items():
        end = po[-1]
        for new, pn in tracks.items():
            start = pn[0]
            frames = start.frame - end.frame
            if new == old or not 1 <= frames <= window:
                continue
            reach = max_speed_mps * frames / fps + 2.0 * PERSON_RADIUS_M
            if float(np.hypot(start.x_m - end.x_m, start.y_m - end.y_m)) <= reach:
                out.handovers.append((old, new))
                out.handover_frames[old].add(end.frame)
                out.handover_frames[new].add(start.frame)
    return out


def attribute(site_path: Path, threshold_m: float) -> dict[str, Any]:
    """Play one site with the default config and attribute its ID switches to its ground truth's artifacts (scored
    where ``evaluate-site`` scores first: everywhere when the site declares its area, else where the ground truth
    annotates people)."""
    site = load_site(site_path)
    assert site.dataset is not None
    fps = site.dataset.fps
    gt = read_gt_csv(site.resolve(site.dataset.ground_truth))
    found = find_artifacts(gt, fps, TrackModel().max_speed_mps)
    _, run = evaluate_site(site_path)
    hull, _ = scored_first(site, gt)
    events: dict[int, list[tuple[str, str, str, float]]] = {}
    kw: dict[str, Any] = {"epoch_ns": DATASET_EPOCH_NS, "fps": fps, "threshold_m": threshold_m, "area": hull}
    scored = score_tracksets(run.tracksets, gt, on_events=events.__setitem__, **kw).metrics
    last: dict[str, str] = {}
    at: dict[str, int] = defaultdict(int)
    for k in sorted(events):
        now = {o: h for kind, o, h, _ in events[k] if kind in ("MATCH", "SWITCH")}
        holder = {h: o for o, h in now.items()}
        for kind, o, _, _ in events[k]:
            if kind != "SWITCH":
                continue
            went = holder.get(last.get(o, ""))
            why = found.near(o, k) or (found.near(went, k) if went else None)
            at[why or "none"] += 1
        last.update(now)
    return {
        "threshold_m": threshold_m,
        "ground_truth": {"people": len(gt.person_ids), **found.counts()},
        "mota": round(scored.mota, 4),
        "idf1": round(scored.idf1, 4),
        "id_switches": scored.id_switches,
        "switches_at_artifacts": {k: v for k, v in sorted(at.items()) if k != "none"},
        "switches_elsewhere": at.get("none", 0),
    }


def _sites(datasets: Path, work: Path) -> dict[str, tuple[Path, float]]:
    out: dict[str, tuple[Path, float]] = {}
    wt, pets, mvdetr = datasets / "wildtrack", datasets / "pets2009_s2l1", datasets / "wildtrack_mvdetr"
    if (wt / "annotations_positions").is_dir():
        out["wildtrack"] = (import_wildtrack(wt, work / "wt").site, 0.5)
        noisy = import_wildtrack(wt, work / "wtn", noise_px=2.0, drop_rate=0.1, seed=1).site
        out["wildtrack_noise2px_drop10"] = (noisy, 0.5)
    if (mvdetr / "detections").is_dir():
        out["wildtrack_mvdetr"] = (import_mot(mvdetr, work / "mvdetr", fps=2.0, shared_detector=MVDETR).site, 0.5)
    if (pets / "detections").is_dir():
        out["pets2009_1.0m"] = (import_mot(pets, work / "pets", fps=7.0, min_confidence=0.5).site, 1.0)
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="bench_ground_truth", description=__doc__.split("\n\n")[0])
    p.add_argument("--datasets", default=str(REPO.parent / "shared" / "datasets"), help="the datasets folder")
    p.add_argument("--out", default="", help="where to import the sites (default: a temporary folder)")
    args = p.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(args.out or tmp)
        sites = _sites(Path(args.datasets), work)
        report: dict[str, Any] = {name: attribute(Path(site), thr) for name, (site, thr) in sites.items()}
    print(json.dumps(report or {"error": f"no development set found under {args.datasets}"}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
