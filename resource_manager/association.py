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
from scipy.optimize import linear_sum_assignment

from common.schema import PairEntry
from resource_manager.align import AlignedView
from resource_manager.births import Births
from resource_manager.config import ManagerConfig
from resource_manager.localize import Measurement, localize_best_pair, localize_least_squares
from resource_manager.match import MatchMatrix, MatchParams, ViewBlobs, get_matcher, match_matrices
from resource_manager.mono import mono_measurement, range_mismatch
from resource_manager.pairs import CameraGeom, PairCandidate, rank_pairs
from resource_manager.poses import PoseEstimate
from resource_manager.track import Tracker, TrackRecord
from resource_manager.views import AllBlobs, build_views, wrap

__all__ = ["Associator", "Outcome"]

FloatArray = npt.NDArray[np.float64]
TWO_PI = 2.0 * math.pi
_FORBID = 1e6
SUPPORT_HALF_M = 0.2
"""Lateral slack (m) of the support gate around a track's predicted bearing: a head is within about this of the
body's centre line. Under half the ~0.5 m between two people walking side by side, so one track's gate does not
reach across to the neighbour's blob (0.25: demo recordings, seed 7, MOTA 0.913 mean of 5 vs 0.931 at 0.2)."""
LINK_BONUS = 0.5
"""Cost bonus (in squared gate units) of the blob with the node-side id a track had last tick."""
OWNER_MIN_MISSES = 3
"""A track that missed this many ticks in a row (its gate has grown) yields fixes nearer a measured track."""
LOOK_ALPHA = 0.1
"""Weight of a new blob in a track's running per-view colour look."""
RERANK_MOVE_M = 0.5
"""A track's camera pairs are re-ranked by the error model when it moved this far (or its views changed)."""


@dataclass(slots=True)
class Outcome:
    pair_entries: list[PairEntry] = field(default_factory=list)
    sensors_in_use: list[str] = field(default_factory=list)
    measured: int = 0
    births: int = 0


@dataclass(slots=True)
class _PairMatch:
    mm: MatchMatrix
    pairs: dict[int, int]
    """row -> column of the accepted matches."""


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
        self._all: AllBlobs | None = None
        self._blank: frozenset[str] = frozenset()
        """Views without any blob at the previous tick."""
        self._rng = np.random.default_rng(0)

    # -- step 1 -----------------------------------------------------------------
    def support(
        self, views: dict[str, ViewBlobs], tracks: list[TrackRecord]
    ) -> tuple[list[dict[str, int]], list[dict[str, int]]]:
        """For each track, sensor id -> index of its own supporting blob, and of blobs it shares.

        Per camera, tracks and blobs inside the gate (bearing, and the feet's floor distance where known) are
        assigned one to one; a track left without a blob whose nearest blob is another track's shares it.
        """
        out: list[dict[str, int]] = [{} for _ in tracks]
        shared: list[dict[str, int]] = [{} for _ in tracks]
        vs = [v for v in views.values() if v.n]
        if not tracks or not vs:
            return out, shared
        txy = np.array([tr.x[:2] for tr in tracks])
        tvar = np.array([max(tr.p[0, 0], tr.p[1, 1]) for tr in tracks])
        k = self.config.match.bearing_gate_sigmas
        links: dict[str, npt.NDArray[np.int64]] = {}
        for t, tr in enumerate(tracks):
            for sid, lid in tr.links.items():
                if sid not in links:
                    links[sid] = np.full(len(tracks), -1, dtype=np.int64)
                links[sid][t] = lid
        # Gates of every (view, track) and normalised distances of every (blob, track) in one pass over all
        # views (per view: the same arithmetic on its rows); only the one-to-one assignment is per view.
        counts = [v.n for v in vs]
        of = np.repeat(np.arange(len(vs)), counts)
        rel = txy[None, :, :] - np.array([v.origin_xy for v in vs])[:, None, :]  # (views, tracks, 2)
        dist = np.maximum(np.hypot(rel[..., 0], rel[..., 1]), 0.3)
        pred = np.arctan2(rel[..., 1], rel[..., 0])
        sig2 = np.array([v.sigma_rad**2 for v in vs])[:, None]
        gate = k * np.sqrt(sig2 + tvar / dist**2) + SUPPORT_HALF_M / dist
        bearing = np.concatenate([v.bearing_rad for v in vs])
        norm = np.abs(wrap(bearing[:, None] - pred[of])) / gate[of]  # (blobs, tracks)
        if any(v.mono_range_m is not None and v.mono_sigma_m is not None for v in vs):
            # Floor distance from the feet (mono.py): along the ray too, within the same number of sigmas.
            known = [v.mono_range_m is not None and v.mono_sigma_m is not None for v in vs]
            pairs = list(zip(vs, known, strict=True))
            rng_m = np.concatenate([v.mono_range_m if ok else np.full(v.n, np.nan) for v, ok in pairs])
            sig_m = np.concatenate([v.mono_sigma_m if ok else np.full(v.n, np.nan) for v, ok in pairs])
            s_r = np.sqrt(sig_m[:, None] ** 2 + tvar[None, :])
            rn = np.abs(rng_m[:, None] - dist[of]) / (k * s_r)
            with_feet = np.repeat(np.array(known), counts)
            norm = np.where(with_feet[:, None], np.hypot(norm, np.nan_to_num(rn, nan=0.0)), norm)
        ok_all = (norm < 1.0) & ~(dist > self.params.max_range_m)[of]
        cost_all = np.where(ok_all, norm**2, _FORBID)
        stop = 0
        for v, n in zip(vs, counts, strict=True):
            sid = v.sensor_id
            sl = slice(stop, stop + n)
            stop += n
            ok = ok_all[sl]
            if not ok.any():
                continue
            # One blob per track and one track per blob, by least total normalised distance (Hungarian):
            # in a crowd, "each track takes its nearest blob" lets one track steal its neighbour's blob.
            # The blob the node kept tracking for it (same local id) gets a bonus, not a free pass: the
            # node's 2D ids swap between people who cross.
            cost = cost_all[sl]
            lids = links.get(sid)
            if lids is not None:
                cost = cost - LINK_BONUS * ((v.local_id[:, None] == lids[None, :]) & ok)
            if self.look_weight > 0 and v.hist_sqrt is not None:
                cost = cost + self._look_cost(sid, v.hist_sqrt, tracks, ok)
            rows_any = np.nonzero(ok.any(axis=1))[0]
            cols_any = np.nonzero(ok.any(axis=0))[0]
            sub = cost[np.ix_(rows_any, cols_any)]
            ri, ci = linear_sum_assignment(sub)
            good = sub[ri, ci] < _FORBID / 2
            blob_of = np.full(len(tracks), -1)
            blob_of[cols_any[ci[good]]] = rows_any[ri[good]]
            claimed = np.zeros(v.n, dtype=bool)
            claimed[blob_of[blob_of >= 0]] = True
            nearest = np.argmin(norm[sl], axis=0)
            near_ok = ok[nearest, np.arange(len(tracks))] & claimed[nearest] & (blob_of < 0)
            for t in np.nonzero(blob_of >= 0)[0].tolist():
                out[t][sid] = int(blob_of[t])
            # A track left without a blob whose nearest is another track's: this person is probably hidden
            # behind it. It explains the blob (no birth from it) but its bearing is the other person's.
            for t in np.nonzero(near_ok)[0].tolist():
                shared[t][sid] = int(nearest[t])
        return out, shared

    def _look_cost(
        self, sid: str, hist_sqrt: FloatArray, tracks: list[TrackRecord], ok: npt.NDArray[np.bool_]
    ) -> FloatArray:
        """(n_blobs, n_tracks) colour dissimilarity of each blob to each track's look in this view, weighted.

        1 - Bhattacharyya coefficient against the running mean of the track's own blobs in this camera: two
        people meeting swap blobs by position alone; by their shirts they seldom do. Tracks without a look
        in this view cost nothing extra.
        """
        out = np.zeros(ok.shape)
        cols = [t for t, tr in enumerate(tracks) if sid in tr.looks and tr.looks[sid].shape[0] == hist_sqrt.shape[1]]
        if cols:
            looks = np.array([tracks[t].looks[sid] for t in cols])
            bc = np.clip(hist_sqrt @ looks.T, 0.0, 1.0)  # (n_blobs, len(cols))
            out[:, cols] = self.look_weight * (1.0 - bc)
        return np.where(ok, out, 0.0)

    def _learn_looks(self, tr: TrackRecord, used_blobs: dict[str, int], views: dict[str, ViewBlobs]) -> None:
        """Fold the colour of the blobs that localised the track into its per-view look."""
        if self.look_weight <= 0:
            return
        for sid, i in used_blobs.items():
            hs = views[sid].hist_sqrt
            if hs is None:
                continue
            h = hs[i]
            old = tr.looks.get(sid)
            if old is None or old.shape != h.shape:
                tr.looks[sid] = h.copy()
            else:
                mixed = (1.0 - LOOK_ALPHA) * old + LOOK_ALPHA * h
                tr.looks[sid] = mixed / max(float(np.linalg.norm(mixed)), 1e-12)

    # -- step 2 -----------------------------------------------------------------
    def _prefetch(
        self,
        keys: set[tuple[str, str]],
        views: dict[str, ViewBlobs],
        tracks: list[TrackRecord],
        cache: dict[tuple[str, str], _PairMatch],
    ) -> None:
        """Eq. 7 for every pair some track will try first, in one vectorised pass."""
        todo = sorted(k for k in keys if k not in cache)
        if not todo:
            return
        pairs = [(views[a], views[b]) for a, b in todo]
        temporals = [self._temporal(a, b, tracks) for a, b in pairs]
        txy = np.array([tr.x[:2] for tr in tracks]).reshape(-1, 2)
        mms = match_matrices(pairs, self.params, temporals, self.threshold, txy)
        for key, mm in zip(todo, mms, strict=True):
            cache[key] = _PairMatch(mm, dict(self.matcher.match(mm.r, self.threshold)))

    @staticmethod
    def _temporal(a: ViewBlobs, b: ViewBlobs, tracks: list[TrackRecord]) -> FloatArray:
        """c_t: 1 where the pair continues a track's previous correspondence (same node blob ids)."""
        temporal = np.zeros((a.n, b.n))
        if a.n and b.n:
            rows = {int(lid): i for i, lid in enumerate(a.local_id)}
            cols = {int(lid): j for j, lid in enumerate(b.local_id)}
            for tr in tracks:
                la, lb = tr.links.get(a.sensor_id), tr.links.get(b.sensor_id)
                if la in rows and lb in cols:
                    temporal[rows[la], cols[lb]] = 1.0
        return temporal

    def _pair_match(
        self, a: ViewBlobs, b: ViewBlobs, tracks: list[TrackRecord], cache: dict[tuple[str, str], _PairMatch]
    ) -> _PairMatch:
        key = (a.sensor_id, b.sensor_id)
        got = cache.get(key)
        if got is not None:
            return got
        temporal = self._temporal(a, b, tracks)
        txy = np.array([tr.x[:2] for tr in tracks]).reshape(-1, 2)
        mm = match_matrices([(a, b)], self.params, [temporal], self.threshold, txy)[0]
        pm = _PairMatch(mm, dict(self.matcher.match(mm.r, self.threshold)))
        cache[key] = pm
        return pm

    def _consistent(self, meas: Measurement, sup: dict[str, int], views: dict[str, ViewBlobs]) -> tuple[list[str], int]:
        """Supporting cameras whose blob points at the measurement, and how many point elsewhere."""
        k = self.config.match.bearing_gate_sigmas
        mono_k = self.config.match.mono_gate_sigmas
        x, y = float(meas.xy[0]), float(meas.xy[1])
        agree: list[str] = []
        against = 0
        for sid, i in sup.items():  # plain floats: a handful of views, numpy per element would cost more
            v = views[sid]
            dx, dy = x - float(v.origin_xy[0]), y - float(v.origin_xy[1])
            dist = max(math.hypot(dx, dy), 0.3)
            off = math.remainder(float(v.bearing_rad[i]) - math.atan2(dy, dx), 2 * math.pi)
            if abs(off) < k * v.sigma_rad + 0.25 / dist and range_mismatch(v, i, meas.xy) < mono_k:
                agree.append(sid)
            else:
                against += 1
        return agree, against

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
        support, shared = self.support(views, tracks)
        cache: dict[tuple[str, str], _PairMatch] = {}
        used: dict[str, set[int]] = {sid: set() for sid in views}
        pose_sigma = {sid: p.sigma_xy_m for sid, p in poses.items()}
        mc = self.config.match
        claimed: set[tuple[str, int]] = set()
        ranked_by: list[list[PairCandidate]] = []
        planned: set[tuple[str, str]] = set()
        for tr, sup in zip(tracks, support, strict=True):
            ranked = (
                self._rank(
                    tr, sup=sup, views=views, pose_sigma=pose_sigma, max_cams=mc.max_pair_cameras, chosen=planned
                )
                if len(sup) >= 2
                else []
            )
            ranked_by.append(ranked)
            if ranked:
                planned.add((min(ranked[0].a, ranked[0].b), max(ranked[0].a, ranked[0].b)))
        self._prefetch(planned, views, tracks, cache)
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
                ranked_sh = self._rank(
                    tr, sup=both, views=views, pose_sigma=pose_sigma, max_cams=mc.max_pair_cameras, chosen=planned
                )
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
            if meas is None:
                if tr.confirmed and self._nobody_there(tr.x[:2]):
                    tr.misses = self.tracker.params.max_misses  # this miss ends it: the person has left
                self.tracker.miss(tr)
                continue
            claimed.update(used_blobs.items())
            links = {sid: int(views[sid].local_id[i]) for sid, i in used_blobs.items()}
            self.tracker.update(tr, meas, links)
            self._learn_looks(tr, used_blobs, views)
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

    def _rank(
        self,
        tr: TrackRecord,
        *,
        sup: dict[str, int],
        views: dict[str, ViewBlobs],
        pose_sigma: dict[str, float],
        max_cams: int,
        chosen: set[tuple[str, str]],
    ) -> list[PairCandidate]:
        """The track's camera pairs, best first by the error model (``chosen``: pairs already matched this tick)."""
        key = frozenset(sup)
        pc = tr.pair_cache
        ranked: list[PairCandidate] = []
        if pc is not None and key <= pc[2] and math.hypot(tr.x[0] - pc[0], tr.x[1] - pc[1]) < RERANK_MOVE_M:
            # Same place, no new camera: the earlier ranking restricted to the cameras that see it now.
            ranked = [c for c in pc[3] if c.a in key and c.b in key]
        if not ranked:
            cams = [CameraGeom(s, views[s].origin_xy, views[s].sigma_rad, pose_sigma.get(s, 0.0)) for s in sup]
            random_pairs = self.config.match.pair_choice == "random"
            ranked = rank_pairs(tr.x[:2].copy(), cams, len(cams) if random_pairs else max_cams)
            tr.pair_cache = (float(tr.x[0]), float(tr.x[1]), key, list(ranked))
        if self.config.match.pair_choice == "random":
            ranked = [ranked[int(i)] for i in self._rng.permutation(len(ranked))]
        tol = self.config.match.pair_reuse_tolerance
        if (
            self.config.match.pair_choice == "error_model"
            and tol > 1.0
            and ranked
            and tuple(sorted((ranked[0].a, ranked[0].b))) not in chosen
        ):
            # A pair already matched this tick and nearly as good saves a whole Eq. 7 matrix.
            reuse = next(
                (c for c in ranked[1:] if c.error_m <= tol * ranked[0].error_m and tuple(sorted((c.a, c.b))) in chosen),
                None,
            )
            if reuse is not None:
                ranked = [reuse, *[c for c in ranked if c is not reuse]]
        return ranked

    def _measure(
        self,
        tr: TrackRecord,
        *,
        sup: dict[str, int],
        views: dict[str, ViewBlobs],
        tracks: list[TrackRecord],
        cache: dict[tuple[str, str], _PairMatch],
        pose_sigma: dict[str, float],
        ranked: list[PairCandidate],
        claimed: set[tuple[str, int]],
    ) -> tuple[Measurement | None, tuple[str, str, int] | None, dict[str, int]]:
        if len(sup) < 2:
            return None, None, {}
        for cand in ranked[:3]:
            a_id, b_id = sorted((cand.a, cand.b))
            a, b = views[a_id], views[b_id]
            pm = self._pair_match(a, b, tracks, cache)
            i, j = sup[a_id], sup[b_id]
            options = []
            if pm.pairs.get(i) == j or pm.mm.r[i, j] > self.threshold:
                # The track's own blobs, if Eq. 7 accepts them as a pair (the matcher may have given one of
                # them to a crossing elsewhere: the track's prediction is the better judge here).
                options.append((i, j))
            options += [(ii, jj) for ii, jj in pm.pairs.items() if (ii == i) != (jj == j)]
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
                if meas is None:
                    continue
                if not math.isfinite(self.tracker.gate_distance(tr, meas)):
                    # Outside the motion gate (a sharp turn): still the same person if the nodes' own 2D
                    # tracks say so in both cameras and the jump is plausible.
                    linked = tr.links.get(a_id) == int(a.local_id[ii]) and tr.links.get(b_id) == int(b.local_id[jj])
                    if not linked or float(np.hypot(*(meas.xy - tr.x[:2]))) > self.config.match.link_gate_m:
                        continue
                if self._owned_elsewhere(tr, meas, tracks):
                    continue  # another, better-followed track explains this fix better: not this one's
                if self._unlike(tr, ((a_id, ii), (b_id, jj)), views):
                    continue  # in someone else's colours
                used = dict(sup)
                used[a_id], used[b_id] = ii, jj
                agree, against = self._consistent(meas, used, views)
                if against > len(agree) - 2 or not self._agreement_ok(meas):
                    continue  # a ghost of two other people's rays: the other cameras look elsewhere
                used = {s: used[s] for s in agree}
                if self.config.manager.fuse_all and len(used) >= 3:
                    lsq = localize_least_squares([(views[s], k) for s, k in used.items()], pose_sigma)
                    if lsq is not None and math.isfinite(self.tracker.gate_distance(tr, lsq)):
                        meas = lsq
                return meas, (a_id, b_id, len(ranked)), used
        return None, None, {}

    def _unlike(self, tr: TrackRecord, blobs: tuple[tuple[str, int], ...], views: dict[str, ViewBlobs]) -> bool:
        """Whether the blobs of a fix look unlike the confirmed track in those views (``match.fix_look_min``)."""
        floor = self.config.match.fix_look_min
        if floor <= 0 or self.look_weight <= 0 or not tr.confirmed:
            return False
        sims: list[float] = []
        for sid, i in blobs:
            hs = views[sid].hist_sqrt
            look = tr.looks.get(sid)
            if hs is not None and look is not None and look.shape[0] == hs.shape[1]:
                sims.append(float(hs[i] @ look))
        return bool(sims) and sum(sims) / len(sims) < floor

    def _owned_elsewhere(self, tr: TrackRecord, meas: Measurement, tracks: list[TrackRecord]) -> bool:
        """Whether another track measured more recently than ``tr`` is nearer (Mahalanobis) to the fix.

        A coasting track's gate keeps growing; without this it takes the fix of the person next to it (the
        neighbour's own, active track loses it, and ids swap when the two walk apart).
        """
        if tr.misses < OWNER_MIN_MISSES:
            return False  # its gate is still about as tight as its neighbours'
        d_tr = self.tracker.gate_distance(tr, meas)
        x, y = float(meas.xy[0]), float(meas.xy[1])
        for u in tracks:
            if u is tr or not u.confirmed:
                continue
            if u.misses >= tr.misses:
                continue
            if abs(float(u.x[0]) - x) > 1.5 or abs(float(u.x[1]) - y) > 1.5:
                continue
            if self.tracker.gate_distance(u, meas) < d_tr:
                return True
        return False

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
