"""One tick of data association: views -> pairs -> Eq. (7) matches -> measurements -> tracks.

1. *Support*: per camera with a known pose, predicted tracks and blobs are assigned one to one (Hungarian)
   on the bearing gate (``bearing_gate_sigmas``: bearing error plus the track's position uncertainty seen
   from that camera) and, for perspective cameras that see the feet, the floor distance (:mod:`.mono`); the
   blob the node tracked for the track last tick (same ``local_id``) gets a bonus, not a free pass (2D ids
   swap in crowds). A track left without a blob whose nearest blob is another track's *shares* it (hidden).
2. *Pair choice*: the cameras that support a track are paired and ranked by the error model
   (:func:`~resource_manager.pairs.rank_pairs`); the best pair whose Eq. (7) match (all blobs of both
   cameras, temporal term from the tracks: same node ids or near a track's prediction) yields a gated
   measurement that the other views and the feet agree with localises the person (Eq. 1 or Eq. 2), or every
   supporting view by least squares with ``fuse_all``. No pair: the views' feet floor points (``mono_updates``);
   nobody's feet there at all: the person has left, the track ends.
3. *Births*: blobs supporting no track are matched pairwise (a bounded number of camera pairs per tick); a
   hypothesis becomes a tentative track unless its feet disagree or other cameras that should see that spot
   see nothing there (ghost veto), best predicted error first.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from common.schema import PairEntry
from resource_manager.births import Births
from resource_manager.config import ManagerConfig
from resource_manager.fixcheck import owned_elsewhere, views_agreeing
from resource_manager.group import HOLD_MIN_HITS, group_fix, hidden_in_group
from resource_manager.ingest.align import AlignedView
from resource_manager.localize import Measurement, localize_best_pair, localize_least_squares
from resource_manager.looks import learn_look, mean_similarity
from resource_manager.match import MatchParams, ViewBlobs, get_matcher
from resource_manager.mono import mono_measurement
from resource_manager.pairmatch import PairMatches
from resource_manager.pairs import PairCandidate, rank_for_track
from resource_manager.poses.solver import PoseEstimate
from resource_manager.room import Room
from resource_manager.support import assign_support
from resource_manager.track import Tracker, TrackRecord
from resource_manager.views import AllBlobs, build_views

__all__ = ["Associator", "Outcome"]

FloatArray = npt.NDArray[np.float64]
TWO_PI = 2.0 * math.pi


@dataclass(slots=True)
class Outcome:
    pair_entries: list[PairEntry] = field(default_factory=list)
    sensors_in_use: list[str] = field(default_factory=list)
    measured: int = 0
    births: int = 0


class Associator:
    """Runs steps 1-3 above against the tracker's tracks."""

    def __init__(self, config: ManagerConfig, tracker: Tracker) -> None:
        mc = config.match
        self.config = config
        self.tracker = tracker
        self.matcher = get_matcher(config.manager.matcher)
        self.params = MatchParams(
            max_range_m=mc.max_range_m,
            width_sigma=mc.width_sigma,
            width_floor=mc.width_floor,
            floor_sigma_m=mc.floor_sigma_m,
            height_sigma=mc.height_sigma,
            use_colour=mc.use_colour,
            temporal_weight=mc.temporal_weight,
            temporal_gate_m=mc.temporal_gate_m,
        )
        self.threshold = mc.threshold
        self.look_weight = mc.look_weight if mc.use_colour else 0.0
        self.births = Births(config, tracker, self.params, self.matcher)
        self.births.in_room = self.in_room
        self._all: AllBlobs | None = None
        self._blank: frozenset[str] = frozenset()
        """Views without any blob at the previous tick."""
        self._rng = np.random.default_rng(0)
        self.room = Room.of(config.planner.room, mc.room_margin_m)
        """``[planner] room``: nobody is fixed or born outside it, no track walks through its walls."""

    def in_room(self, xy: FloatArray) -> bool:
        return self.room is None or self.room.holds(xy)

    # -- step 1 -----------------------------------------------------------------
    def support(
        self, views: dict[str, ViewBlobs], tracks: list[TrackRecord]
    ) -> tuple[list[dict[str, int]], list[dict[str, int]]]:
        """For each track, sensor id -> index of its own supporting blob, and of blobs it shares (:mod:`.support`)."""
        return assign_support(
            views,
            tracks,
            gate_sigmas=self.config.match.bearing_gate_sigmas,
            max_range_m=self.params.max_range_m,
            look_weight=self.look_weight,
        )

    # -- step 2 -----------------------------------------------------------------
    def run(
        self,
        aligned: dict[str, AlignedView],
        poses: dict[str, PoseEstimate],
        sigma_of: Callable[[str], float],
        t_ns: int,
        *,
        bodies: dict[str, float] | None = None,
        fovs: dict[str, tuple[float, float]] | None = None,
        mono: dict[str, tuple[float, float, float, float]] | None = None,
        blind: frozenset[str] = frozenset(),
    ) -> Outcome:
        """One tick of steps 1-3.

        ``blind``: sensors that cannot detect anyone now (a robot driving to a view-plan goal, then relearning
        its background): their blank views are no evidence that nobody is there.
        """
        views = build_views(aligned, poses, sigma_of, bodies, fovs, mono=mono)
        blank = frozenset(sid for sid, v in views.items() if v.n == 0)
        self._all = AllBlobs.of(
            views,
            self.config.match.bearing_gate_sigmas,
            self.config.match.mono_gate_sigmas,
            excused=(blank - self._blank) | (blank & blind),
        )
        self._blank = blank
        out = Outcome(sensors_in_use=sorted(views))
        tracks = sorted(self.tracker.tracks, key=lambda tr: (not tr.confirmed, tr.born_ns, tr.serial))
        if self.room is not None:
            for tr in tracks:
                self.room.stop_at_walls(tr)
        support, shared = self.support(views, tracks)
        cache = PairMatches(views, tracks, self.params, self.matcher, self.threshold)
        used: dict[str, set[int]] = {sid: set() for sid in views}
        pose_sigma = {sid: p.sigma_xy_m for sid, p in poses.items()}
        mc = self.config.match
        claimed: set[tuple[str, int]] = set()
        ranked_by: list[list[PairCandidate]] = []
        planned: set[tuple[str, str]] = set()
        for tr, sup in zip(tracks, support, strict=True):
            ranked = self._rank(tr, sup, views, pose_sigma, planned) if len(sup) >= 2 else []
            ranked_by.append(ranked)
            if ranked:
                planned.add((min(ranked[0].a, ranked[0].b), max(ranked[0].a, ranked[0].b)))
        cache.prefetch(planned)
        # Who owns each blob: only the group hold reads it (``group_coast_s`` > 0).
        owner = (
            {(sid, i): u for u, sp in zip(tracks, support, strict=True) for sid, i in sp.items()}
            if self.config.match.group_coast_s > 0
            else {}
        )
        for tr, sup, sh, ranked in zip(tracks, support, shared, ranked_by, strict=True):
            for sid, i in itertools.chain(sup.items(), sh.items()):
                used[sid].add(i)
            meas, entry, used_blobs = self._measure(
                tr,
                sup=sup,
                views=views,
                tracks=tracks,
                cache=cache,
                pose_sigma=pose_sigma,
                ranked=ranked,
                claimed=claimed,
            )
            if meas is None and mc.shared_pairs and sup and sh and len(sup) + len(sh) >= 2:
                # Hidden in some views behind a neighbour (one blob there for both, "views disagree"): pair its
                # own blobs with those shared ones. The shared bearing is the neighbour's, so the fix is off by
                # at most their spacing; the motion gate and the other views still judge it.
                both = {**sh, **sup}
                ranked_sh = self._rank(tr, both, views, pose_sigma, planned)
                ranked_sh = [c for c in ranked_sh if c.a in sup or c.b in sup]
                meas, entry, used_blobs = self._measure(
                    tr,
                    sup=both,
                    views=views,
                    tracks=tracks,
                    cache=cache,
                    pose_sigma=pose_sigma,
                    ranked=ranked_sh,
                    claimed=set(),
                )
                if meas is not None:
                    used_blobs = {s: i for s, i in used_blobs.items() if s in sup}  # links: own blobs only
            if meas is None:
                # No pair localises it this tick: the views that still follow it (same node-side blob) steer it
                # by bearing alone, so the prediction stays on the person while the stereo pair is broken.
                if mc.mono_updates and sup:
                    # The views' own floor points (mono.py): one view is enough to stay on the person.
                    mono_meas = mono_measurement([(views[s], i) for s, i in sup.items()])
                    if mono_meas is not None and math.isfinite(self.tracker.gate_distance(tr, mono_meas)):
                        meas, entry, used_blobs = mono_meas, None, dict(mono_meas.blobs)
                if meas is None and mc.bearing_updates:
                    for sid, i in sup.items():
                        v = views[sid]
                        if tr.links.get(sid) == int(v.local_id[i]):
                            self.tracker.bearing_update(tr, v.origin_xy, float(v.bearing_rad[i]), v.sigma_rad)
            if meas is None and len(sup) == 1 and sh and tr.confirmed:
                meas = self._group_measure(tr, sup, sh, views, t_ns)
                if meas is not None:
                    entry, used_blobs = None, dict(sup)
            elif meas is not None and entry is not None:
                tr.fixed_ns = t_ns
            if meas is None and tr.confirmed and sh and self._hold_in_group(tr, sup, sh, views, t_ns, owner):
                continue  # hidden in its group: held, no miss counted
            if meas is None:
                if tr.confirmed and self._nobody_there(tr.x[:2]):
                    tr.misses = self.tracker.params.max_misses  # this miss ends it: the person has left
                self.tracker.miss(tr)
                continue
            claimed.update(used_blobs.items())
            links = {sid: int(views[sid].local_id[i]) for sid, i in used_blobs.items()}
            self.tracker.update(tr, meas, links)
            if self.look_weight > 0:
                learn_look(tr, used_blobs, views)
            for sid in sup:
                if sid not in used_blobs:
                    tr.links.pop(sid, None)  # that camera's blob is someone else's now
            out.measured += 1
            if entry is not None and tr.track_id:
                out.pair_entries.append(
                    PairEntry(
                        track_id=tr.track_id,
                        sensor_a=entry[0],
                        sensor_b=entry[1],
                        predicted_error_m=float(min(max(meas.predicted_error_m, 0.0), 1e5)),
                        method=meas.method,
                        candidates=entry[2],
                    )
                )
        out.births = self.births.run(views, used, pose_sigma, t_ns, self._agreement_ok)
        return out

    def _group_measure(
        self, tr: TrackRecord, sup: dict[str, int], sh: dict[str, int], views: dict[str, ViewBlobs], t_ns: int
    ) -> Measurement | None:
        """A fix from the track's own rays and the extents of the blobs it shares (:mod:`.group`), if allowed.

        Only for ``group_coast_s`` after the track's last stereo fix, with an own blob that continues the node's
        2D track it followed, inside the motion gate and where the cameras that could see it see someone.
        """
        limit_s = self.config.match.group_coast_s
        if limit_s <= 0 or (t_ns - tr.fixed_ns) / 1e9 > limit_s:
            return None
        if not any(tr.links.get(sid) == int(views[sid].local_id[i]) for sid, i in sup.items()):
            return None
        meas = group_fix(tr.x[:2], sup, sh, views)
        if (
            meas is None
            or not self.in_room(meas.xy)
            or not math.isfinite(self.tracker.gate_distance(tr, meas))
            or not self._agreement_ok(meas)
        ):
            return None
        return meas

    def _hold_in_group(  # noqa: PLR0917
        self,
        tr: TrackRecord,
        sup: dict[str, int],
        sh: dict[str, int],
        views: dict[str, ViewBlobs],
        t_ns: int,
        owner: dict[tuple[str, int], TrackRecord],
    ) -> bool:
        """Hold a well-followed track hidden in a merged group (:func:`.group.hidden_in_group`) where it is: no
        miss counted, no velocity, for ``group_coast_s`` at most; at least one blob it shares must be a confirmed
        group mate's."""
        limit_s = self.config.match.group_coast_s
        if limit_s <= 0 or (t_ns - tr.fixed_ns) / 1e9 > limit_s or tr.hits < HOLD_MIN_HITS:
            return False
        mate = any(u is not None and u is not tr and u.confirmed for u in (owner.get(b) for b in sh.items()))
        if not mate or not hidden_in_group(tr.x[:2], sup, sh, views):
            return False
        tr.x[2:] = 0.0  # where it was last seen: its mates' velocity carried a standing person off (replays)
        self.tracker.hold(tr)
        return True

    def _rank(
        self,
        tr: TrackRecord,
        sup: dict[str, int],
        views: dict[str, ViewBlobs],
        pose_sigma: dict[str, float],
        chosen: set[tuple[str, str]],
    ) -> list[PairCandidate]:
        mc = self.config.match
        return rank_for_track(
            tr,
            sup=sup,
            views=views,
            pose_sigma=pose_sigma,
            max_cams=mc.max_pair_cameras,
            chosen=chosen,
            choice=mc.pair_choice,
            reuse_tolerance=mc.pair_reuse_tolerance,
            rng=self._rng,
        )

    def _measure(
        self,
        tr: TrackRecord,
        *,
        sup: dict[str, int],
        views: dict[str, ViewBlobs],
        tracks: list[TrackRecord],
        cache: PairMatches,
        pose_sigma: dict[str, float],
        ranked: list[PairCandidate],
        claimed: set[tuple[str, int]],
    ) -> tuple[Measurement | None, tuple[str, str, int] | None, dict[str, int]]:
        if len(sup) < 2:
            return None, None, {}
        for cand in ranked[:3]:
            a_id, b_id = sorted((cand.a, cand.b))
            a, b = views[a_id], views[b_id]
            pm = cache.get(a_id, b_id)
            i, j = sup[a_id], sup[b_id]
            options = []
            if pm.pairs.get(i) == j or pm.mm.r[i, j] > self.threshold:
                # The track's own blobs, if Eq. 7 accepts them as a pair (the matcher may have given one of
                # them to a crossing elsewhere: the track's prediction is the better judge here).
                options.append((i, j))
            options += [(ii, jj) for ii, jj in pm.pairs.items() if (ii == i) != (jj == j)]
            # Every option the checks let through, and the one nearest the prediction (Mahalanobis) is taken: in
            # a crossing the own blobs may be the neighbour's (the node's 2D ids swapped) while Eq. 7 pairs one of
            # them with the track's true blob (six seed 3, 27.7 s: own pair 0.2 m off, gate 8.2; Eq. 7's 0.02).
            found: list[tuple[float, Measurement, dict[str, int]]] = []
            judge = tr.confirmed and tr.hits >= HOLD_MIN_HITS  # well followed (the group hold's threshold)
            for ii, jj in options:
                if (a_id, ii) in claimed and (b_id, jj) in claimed:
                    continue  # both blobs already localised another track this tick: a duplicate
                meas = localize_best_pair(
                    a,
                    ii,
                    b,
                    jj,
                    sigma_xy_a=pose_sigma.get(a_id, 0.0),
                    sigma_xy_b=pose_sigma.get(b_id, 0.0),
                    width_rel_sigma=self.config.match.width_rel_sigma,
                )
                if meas is None or not self.in_room(meas.xy):
                    continue
                gate_d = self.tracker.gate_distance(tr, meas)
                if not math.isfinite(gate_d):
                    # Outside the motion gate (a sharp turn): still the same person if the nodes' own 2D
                    # tracks say so in both cameras and the jump is plausible.
                    linked = tr.links.get(a_id) == int(a.local_id[ii]) and tr.links.get(b_id) == int(b.local_id[jj])
                    if not linked or float(np.hypot(*(meas.xy - tr.x[:2]))) > self.config.match.link_gate_m:
                        continue
                if owned_elsewhere(self.tracker, tr, meas, tracks):
                    continue  # another, better-followed track explains this fix better: not this one's
                if self._unlike(tr, ((a_id, ii), (b_id, jj)), views):
                    continue  # in someone else's colours
                used = dict(sup)
                used[a_id], used[b_id] = ii, jj
                agree, against = views_agreeing(
                    meas, used, views, self.config.match.bearing_gate_sigmas, self.config.match.mono_gate_sigmas
                )
                # A confirmed track's fix that three or more of its cameras point at, and none elsewhere, is no ghost:
                # one more camera with nobody there missed a detection (min_view_agreement 0.8 asks 4 of 4 cameras).
                outvoted = tr.confirmed and len(agree) >= 3 and not against
                if against > len(agree) - 2 or not (outvoted or self._agreement_ok(meas)):
                    continue  # a ghost of two other people's rays: the other cameras look elsewhere
                used = {s: used[s] for s in agree}
                if self.config.manager.fuse_all and len(used) >= 3:
                    lsq = localize_least_squares([(views[s], k) for s, k in used.items()], pose_sigma)
                    if lsq is not None and math.isfinite(self.tracker.gate_distance(tr, lsq)):
                        meas = lsq
                found.append((gate_d, meas, used))
                if not judge:
                    break  # only a well-followed track's prediction judges (a young one's may sit between people)
            if found:
                _, meas, used = min(found, key=lambda f: f[0])  # the first of equals: own blobs first
                return meas, (a_id, b_id, len(ranked)), used
        return None, None, {}

    def _unlike(self, tr: TrackRecord, blobs: tuple[tuple[str, int], ...], views: dict[str, ViewBlobs]) -> bool:
        """Whether the blobs of a fix look unlike the confirmed track in those views (``match.fix_look_min``)."""
        floor = self.config.match.fix_look_min
        if floor <= 0 or self.look_weight <= 0 or not tr.confirmed:
            return False
        pairs = []
        for sid, i in blobs:
            hs = views[sid].hist_sqrt
            pairs.append((None if hs is None else hs[i], tr.looks.get(sid)))
        sim = mean_similarity(pairs)
        return sim is not None and sim < floor

    # -- step 3 -----------------------------------------------------------------
    def _nobody_there(self, xy: FloatArray) -> bool:
        """No camera that could see ``xy`` has any blob toward it (and at least two could)."""
        a = self._all
        if a is None:
            return False
        agree, total = a.agreement(xy, self.params.max_range_m, occluders=False)
        return total >= 2 and agree == 0

    def _agreement_ok(self, meas: Measurement) -> bool:
        """Enough of the cameras that could see the spot have a blob (own or an occluder's) toward it."""
        a = self._all
        if a is None:
            return True
        agree, total = a.agreement(meas.xy, self.params.max_range_m)
        if total < 3:
            return True
        return agree >= self.config.match.min_view_agreement * total
