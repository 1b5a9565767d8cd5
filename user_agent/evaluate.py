"""Tracking accuracy against ground truth: CLEAR-MOT, ID measures and position error.

Pure (no zenoh, no mcap): values in, values out.

* **CLEAR-MOT** (Bernardin & Stiefelhagen 2008), with the event rules of
  py-motmetrics: per frame, a ground-truth object keeps the hypothesis it was
  matched to last time if that pairing is still valid (distance within the
  threshold); the remaining objects and hypotheses are paired by minimum total
  distance (Hungarian algorithm); a pairing that differs from the object's last
  one is an ID switch; unpaired objects are misses, unpaired hypotheses false
  positives. ``MOTA = 1 - (misses + FP + switches) / objects``,
  ``MOTP = sum of matched distances / matches`` (metres here, as in the paper's
  original definition, lower is better).
* **ID measures** (Ristani et al. 2016): one global one-to-one assignment of
  ground-truth ids to track ids maximising the number of frames where they are
  within the threshold (IDTP); ``IDF1 = 2 IDTP / (GT + hypotheses)``.
* **Error**: mean and 90th percentile of the matched distances.
* **Scored area** (optional): where the ground truth annotates people at all (e.g. one camera's view, or a
  dataset's annotated grid). A track farther than the threshold outside it is neither a match nor a false
  positive: nobody can say whether someone is there. Every ground-truth object counts wherever it is.

:class:`MotAccumulator` takes distance matrices (``nan`` = not allowed), like
py-motmetrics' accumulator, so it can be checked against that library's
published worked example; :func:`evaluate_positions` builds those matrices from
floor positions, and :func:`hypotheses_from_tracksets` lines recorded
``TrackSet`` messages up with the ground truth's frames.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import asdict, dataclass, field

import numpy as np
import numpy.typing as npt
from scipy.optimize import linear_sum_assignment

from common.errors import ConfigError
from common.schema import Track, TrackSet
from user_agent.groundtruth import GroundTruth, GtPoint

__all__ = [
    "DEFAULT_STATES",
    "HypPoint",
    "MotAccumulator",
    "MotMetrics",
    "evaluate_positions",
    "frame_distances",
    "hypotheses_from_tracksets",
    "unseen_spans",
    "within_area",
    "within_area_many",
]

MOSTLY_TRACKED = 0.8
"""An object matched in at least this fraction of its frames is mostly tracked (CLEAR-MOT's MT)..."""
MOSTLY_LOST = 0.2
"""...in less than this fraction, mostly lost (ML); partially tracked between."""

DEFAULT_STATES: tuple[str, ...] = ("confirmed", "coasting")
"""Track states scored by default (tentative tracks are not yet claims)."""


@dataclass(frozen=True, slots=True)
class HypPoint:
    """One track's floor position at one ground-truth frame."""

    track_id: str
    x_m: float
    y_m: float


@dataclass(frozen=True, slots=True)
class MotMetrics:
    """The figures of one evaluation (counts are over all frames)."""

    frames: int
    objects: int
    """Ground-truth object appearances (sum over frames)."""
    hypotheses: int
    matches: int
    """Matched pairs that continue the object's previous pairing (switches excluded)."""
    id_switches: int
    false_positives: int
    misses: int
    mota: float
    motp_m: float
    precision: float
    recall: float
    idtp: int
    idfp: int
    idfn: int
    idp: float
    idr: float
    idf1: float
    mean_error_m: float
    p90_error_m: float
    gt_ids: int
    """Distinct ground-truth identities."""
    track_ids: int
    """Distinct track identities."""
    mostly_tracked: int
    partially_tracked: int
    mostly_lost: int
    threshold_m: float = math.nan
    fragmentations: int = 0
    """Times a person, followed before, was followed again after frames nobody followed them (py-motmetrics' FM)."""
    ids_per_person: float = math.nan
    """Distinct track ids matched to each person, on average over the people matched at all."""

    def to_dict(self) -> dict[str, float | int | None]:
        """JSON-ready: NaN (undefined, e.g. no objects) becomes None."""
        out: dict[str, float | int | None] = {}
        for key, value in asdict(self).items():
            if isinstance(value, float) and not math.isfinite(value):
                out[key] = None
            elif isinstance(value, float):
                out[key] = round(value, 6)
            else:
                out[key] = value
        return out


def _div(a: float, b: float) -> float:
    return a / b if b else math.nan


@dataclass
class MotAccumulator:
    """Frame-by-frame CLEAR-MOT event accumulator (py-motmetrics rules)."""

    last_match: dict[str, str] = field(default_factory=dict)
    """Object id -> the hypothesis it was last matched to (kept across gaps)."""
    frames: int = 0
    objects: int = 0
    hypotheses: int = 0
    matches: int = 0
    switches: int = 0
    false_positives: int = 0
    misses: int = 0
    distances: list[float] = field(default_factory=list)
    obj_frames: dict[str, int] = field(default_factory=dict)
    """Object id -> frames it appears in."""
    obj_tracked: dict[str, int] = field(default_factory=dict)
    """Object id -> frames it was matched in."""
    hyp_frames: dict[str, int] = field(default_factory=dict)
    co_valid: dict[tuple[str, str], int] = field(default_factory=dict)
    """(object, hypothesis) -> frames where both exist within the threshold (for IDF1)."""
    followed: dict[str, bool] = field(default_factory=dict)
    """Object id -> whether it was matched in its latest frame (for fragmentations)."""
    fragmentations: int = 0
    obj_hyps: dict[str, set[str]] = field(default_factory=dict)
    """Object id -> every hypothesis it was matched to."""

    def _count(self, gt_ids: Sequence[str], hyp_ids: Sequence[str], valid: npt.NDArray[np.bool_]) -> None:
        """Count a frame: its objects and hypotheses, and the pairs within the threshold (for IDF1)."""
        self.frames += 1
        self.objects += len(gt_ids)
        self.hypotheses += len(hyp_ids)
        for o in gt_ids:
            self.obj_frames[o] = self.obj_frames.get(o, 0) + 1
        for h in hyp_ids:
            self.hyp_frames[h] = self.hyp_frames.get(h, 0) + 1
        for i, j in zip(*np.nonzero(valid), strict=True):
            key = (gt_ids[i], hyp_ids[j])
            self.co_valid[key] = self.co_valid.get(key, 0) + 1

    def update(
        self, gt_ids: Sequence[str], hyp_ids: Sequence[str], dist: Sequence[Sequence[float]] | npt.NDArray[np.float64]
    ) -> list[tuple[str, str, str, float]]:
        """Add one frame.

        Args:
            gt_ids: ground-truth object ids present in the frame.
            hyp_ids: hypothesis (track) ids present in the frame.
            dist: ``len(gt_ids) x len(hyp_ids)`` distances; ``nan`` forbids a pairing.

        Returns:
            The frame's events ``(type, object, hypothesis, distance)`` with type
            MATCH, SWITCH, MISS or FP.

        Raises:
            ConfigError: if the matrix shape does not fit the ids.
        """
        d = np.asarray(dist, dtype=np.float64).reshape(len(gt_ids), len(hyp_ids))
        if len(set(gt_ids)) != len(gt_ids) or len(set(hyp_ids)) != len(hyp_ids):
            raise ConfigError(f"duplicate ids in one frame: objects {list(gt_ids)}, hypotheses {list(hyp_ids)}")
        valid = np.isfinite(d)
        self._count(gt_ids, hyp_ids, valid)

        events: list[tuple[str, str, str, float]] = []
        free_o = set(range(len(gt_ids)))
        free_h = set(range(len(hyp_ids)))
        hyp_index = {h: j for j, h in enumerate(hyp_ids)}
        # 1. Keep last frame's pairings that are still valid (CLEAR-MOT's continuity rule).
        for i, o in enumerate(gt_ids):
            j = hyp_index.get(self.last_match.get(o, ""), -1)
            if j >= 0 and j in free_h and valid[i, j]:
                events.append(("MATCH", o, hyp_ids[j], float(d[i, j])))
                free_o.discard(i)
                free_h.discard(j)
        # 2. Minimum-cost assignment of the rest; forbidden pairs cost more than any valid set.
        rows, cols = sorted(free_o), sorted(free_h)
        if rows and cols:
            sub = d[np.ix_(rows, cols)]
            ok = np.isfinite(sub)
            if ok.any():
                big = 1.0 + float(np.abs(sub[ok]).sum()) * 2.0 + 1.0
                cost = np.where(ok, sub, big * (len(rows) + len(cols)))
                for r, c in zip(*linear_sum_assignment(cost), strict=True):
                    if not ok[r, c]:
                        continue
                    i, j = rows[r], cols[c]
                    o, h = gt_ids[i], hyp_ids[j]
                    kind = "SWITCH" if o in self.last_match and self.last_match[o] != h else "MATCH"
                    events.append((kind, o, h, float(d[i, j])))
                    free_o.discard(i)
                    free_h.discard(j)
        self._count_fragments(gt_ids, {o for _, o, _, _ in events})
        for kind, o, h, dd in events:
            self.obj_hyps.setdefault(o, set()).add(h)
            self.last_match[o] = h
            self.distances.append(dd)
            self.obj_tracked[o] = self.obj_tracked.get(o, 0) + 1
            if kind == "SWITCH":
                self.switches += 1
            else:
                self.matches += 1
        for i in sorted(free_o):
            events.append(("MISS", gt_ids[i], "", math.nan))
            self.misses += 1
        for j in sorted(free_h):
            events.append(("FP", "", hyp_ids[j], math.nan))
            self.false_positives += 1
        return events

    def _id_measures(self) -> tuple[int, int, int]:
        objs = sorted(self.obj_frames)
        hyps = sorted(self.hyp_frames)
        idtp = 0
        if objs and hyps:
            tp = np.zeros((len(objs), len(hyps)))
            oi = {o: i for i, o in enumerate(objs)}
            hi = {h: j for j, h in enumerate(hyps)}
            for (o, h), n in self.co_valid.items():
                tp[oi[o], hi[h]] = n
            r, c = linear_sum_assignment(-tp)
            idtp = int(tp[r, c].sum())
        return idtp, self.hypotheses - idtp, self.objects - idtp

    def _count_fragments(self, gt_ids: Sequence[str], matched: set[str]) -> None:
        """A person followed before, then not, is followed again: one fragmentation."""
        for o in gt_ids:
            if o in matched:
                if self.followed.get(o) is False:
                    self.fragmentations += 1
                self.followed[o] = True
            elif o in self.followed:
                self.followed[o] = False

    def summary(self, threshold_m: float = math.nan) -> MotMetrics:
        """The metrics of everything accumulated so far."""
        detections = self.matches + self.switches
        idtp, idfp, idfn = self._id_measures()
        ratios = [self.obj_tracked.get(o, 0) / n for o, n in self.obj_frames.items()]
        errs = np.asarray(self.distances, dtype=np.float64)
        return MotMetrics(
            frames=self.frames,
            objects=self.objects,
            hypotheses=self.hypotheses,
            matches=self.matches,
            id_switches=self.switches,
            false_positives=self.false_positives,
            misses=self.misses,
            mota=1.0 - _div(self.misses + self.false_positives + self.switches, self.objects),
            motp_m=_div(float(errs.sum()), detections),
            precision=_div(detections, detections + self.false_positives),
            recall=_div(detections, self.objects),
            idtp=idtp,
            idfp=idfp,
            idfn=idfn,
            idp=_div(idtp, idtp + idfp),
            idr=_div(idtp, idtp + idfn),
            idf1=_div(2 * idtp, self.objects + self.hypotheses),
            mean_error_m=float(errs.mean()) if errs.size else math.nan,
            p90_error_m=float(np.percentile(errs, 90)) if errs.size else math.nan,
            gt_ids=len(self.obj_frames),
            track_ids=len(self.hyp_frames),
            mostly_tracked=sum(r >= MOSTLY_TRACKED for r in ratios),
            partially_tracked=sum(MOSTLY_LOST <= r < MOSTLY_TRACKED for r in ratios),
            mostly_lost=sum(r < MOSTLY_LOST for r in ratios),
            threshold_m=threshold_m,
            fragmentations=self.fragmentations,
            ids_per_person=_div(sum(len(h) for h in self.obj_hyps.values()), len(self.obj_hyps)),
        )


def within_area(area: npt.NDArray[np.float64], x_m: float, y_m: float, margin_m: float) -> bool:
    """Whether a floor point lies inside a convex, counter-clockwise polygon grown by ``margin_m``."""
    return bool(within_area_many(area, np.array([[x_m, y_m]]), margin_m)[0])


def within_area_many(
    area: npt.NDArray[np.float64], xy: npt.NDArray[np.float64], margin_m: float
) -> npt.NDArray[np.bool_]:
    """(n,) whether each floor point of ``xy`` (n, 2) lies inside a convex, counter-clockwise polygon grown by
    ``margin_m``."""
    a = np.asarray(area, dtype=np.float64)
    p = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    edge = np.roll(a, -1, axis=0) - a
    length = np.maximum(np.hypot(edge[:, 0], edge[:, 1]), 1e-12)
    rel = p[:, None, :] - a[None, :, :]  # (n, k, 2)
    # Signed distance of each point to the left of each edge; inside a CCW convex polygon all are >= 0.
    side = (edge[:, 0] * rel[:, :, 1] - edge[:, 1] * rel[:, :, 0]) / length
    t = np.clip((rel[:, :, 0] * edge[:, 0] + rel[:, :, 1] * edge[:, 1]) / length**2, 0.0, 1.0)
    near = np.hypot(rel[:, :, 0] - t * edge[:, 0], rel[:, :, 1] - t * edge[:, 1])
    return np.asarray(np.all(side >= 0, axis=1) | (np.min(near, axis=1) <= margin_m), dtype=bool)


def evaluate_positions(
    gt: GroundTruth,
    hyps: dict[int, list[HypPoint]],
    threshold_m: float = 0.5,
    frames: Iterable[int] | None = None,
    on_events: Callable[[int, list[tuple[str, str, str, float]]], None] | None = None,
    *,
    area: npt.NDArray[np.float64] | None = None,
) -> MotMetrics:
    """Score floor positions against the ground truth.

    Args:
        gt: the ground truth, by frame.
        hyps: the tracks' positions, by the same frame numbers.
        threshold_m: a track farther than this from a person cannot be that person.
        frames: which frames to score (default: every ground-truth frame).
        on_events: called with each scored frame's number and its events (:meth:`MotAccumulator.update`),
            for a scorer that also wants to know where frames were lost.
        area: (k, 2) convex counter-clockwise polygon where the ground truth annotates people
            (:meth:`GroundTruth.area`); tracks farther than ``threshold_m`` outside it are not scored.
    """
    if not threshold_m > 0:
        raise ConfigError(f"threshold must be > 0 m, got {threshold_m}")
    acc = MotAccumulator()
    for k in sorted(gt.frames) if frames is None else sorted(frames):
        objs = gt.frames.get(k, [])
        hs = hyps.get(k, [])
        if area is not None and hs:
            inside = within_area_many(area, np.array([[h.x_m, h.y_m] for h in hs]), threshold_m)
            hs = [h for h, there in zip(hs, inside.tolist(), strict=True) if there]
        events = acc.update(
            [p.person_id for p in objs], [h.track_id for h in hs], frame_distances(objs, hs, threshold_m)
        )
        if on_events is not None:
            on_events(k, events)
    return acc.summary(threshold_m)


def frame_distances(objs: Sequence[GtPoint], hyps: Sequence[HypPoint], threshold_m: float) -> npt.NDArray[np.float64]:
    """One frame's (people x tracks) floor distances, NaN where farther than ``threshold_m`` (cannot match)."""
    d = np.full((len(objs), len(hyps)), math.nan)
    if objs and hyps:
        a = np.array([[p.x_m, p.y_m] for p in objs])
        b = np.array([[h.x_m, h.y_m] for h in hyps])
        e = np.linalg.norm(a[:, None, :] - b[None, :, :], axis=2)
        d = np.where(e <= threshold_m, e, math.nan)
    return d


def hypotheses_from_tracksets(
    tracksets: Iterable[TrackSet],
    epoch_ns: int,
    fps: float,
    frames: Iterable[int],
    *,
    max_gap_s: float = 0.25,
    states: Sequence[str] = DEFAULT_STATES,
    start_ns: int | None = None,
    skip: Sequence[tuple[int, int]] = (),
) -> tuple[dict[int, list[HypPoint]], list[int]]:
    """Line recorded TrackSets up with ground-truth frames.

    Frame ``k`` is world time ``(k - 1) / fps`` after ``epoch_ns``. For each
    frame and each manager, the TrackSet nearest in time (within
    ``max_gap_s``) is taken and each track moved to the frame's instant by its
    own velocity (a gap of at most half a fusion tick). Every frame from the
    first one (or from ``start_ns``, e.g. the end of a run's warm-up) up to the
    last TrackSet is scored: a frame with no TrackSet near enough, before the
    first one included, has no hypotheses (all its people count as misses).
    Frames after the last TrackSet (the run had ended), and those inside the
    (start, end) ns spans of ``skip`` (:func:`unseen_spans`: what the recording
    did not see), are not scored. An id in several managers' sets (zone managers
    at a handover: each published the person at its own instants) is one
    hypothesis, from the set nearest the frame.

    Returns:
        (hypotheses by frame, the frames to score).
    """
    if fps <= 0:
        raise ConfigError(f"fps must be > 0, got {fps}")
    by_mgr: dict[str, list[TrackSet]] = {}
    for ts in tracksets:
        by_mgr.setdefault(ts.manager_id, []).append(ts)
    if not by_mgr:
        return {}, []
    stamps = {m: np.array([t.stamp_ns for t in sorted(v, key=lambda t: t.stamp_ns)]) for m, v in by_mgr.items()}
    ordered = {m: sorted(v, key=lambda t: t.stamp_ns) for m, v in by_mgr.items()}
    last = max(int(s[-1]) for s in stamps.values())
    gap_ns = int(max_gap_s * 1e9)
    out: dict[int, list[HypPoint]] = {}
    scored: list[int] = []
    for k in sorted(frames):
        t_ns = epoch_ns + round((k - 1) / fps * 1e9)
        if t_ns > last + gap_ns or (start_ns is not None and t_ns < start_ns):
            continue
        if any(a < t_ns < b for a, b in skip):
            continue
        scored.append(k)
        pts: dict[str, tuple[int, HypPoint]] = {}
        for m, s in stamps.items():
            i = int(np.searchsorted(s, t_ns))
            best = min((j for j in (i - 1, i) if 0 <= j < len(s)), key=lambda j: abs(int(s[j]) - t_ns))
            if abs(int(s[best]) - t_ns) > gap_ns:
                continue
            ts = ordered[m][best]
            dt = (t_ns - ts.stamp_ns) / 1e9
            for tr in ts.tracks:
                old = pts.get(tr.track_id)
                if tr.state in states and (old is None or abs(ts.stamp_ns - t_ns) < old[0]):
                    pts[tr.track_id] = (abs(ts.stamp_ns - t_ns), HypPoint(tr.track_id, *_moved(tr, dt)))
        out[k] = [p for _, p in pts.values()]
    return out, scored


def _moved(tr: Track, dt: float) -> tuple[float, float]:
    """A track's position carried ``dt`` seconds by its velocity."""
    return tr.x_m + tr.vx_mps * dt, tr.y_m + tr.vy_mps * dt


def unseen_spans(tracksets: Iterable[TrackSet], max_gap_s: float = 0.25) -> list[tuple[int, int]]:
    """Spans (ns) of the run whose TrackSets the recording lost: what was published but not recorded.

    A manager numbers its TrackSets (``seq``, one per tick); between two recorded ones whose numbers are not
    consecutive, the ones in between were published and lost on the way (a recorder that had to drop). Frames
    there are not the tracker's misses, so scoring skips them. A manager that published nothing (down,
    restarted: ``seq`` starts again) leaves no such gap, and its silence is scored. Each span leaves out the
    ``max_gap_s`` next to the TrackSets that bound it (they still stand for those frames).
    """
    by_mgr: dict[str, list[TrackSet]] = {}
    for ts in tracksets:
        by_mgr.setdefault(ts.manager_id, []).append(ts)
    gap_ns = int(max_gap_s * 1e9)
    spans: list[tuple[int, int]] = []
    for sets in by_mgr.values():
        ordered = sorted(sets, key=lambda t: t.stamp_ns)
        for a, b in itertools.pairwise(ordered):
            if b.seq > a.seq + 1 and b.stamp_ns - a.stamp_ns > 2 * gap_ns:
                spans.append((a.stamp_ns + gap_ns, b.stamp_ns - gap_ns))
    return sorted(spans)
