"""The tracker: every track predicted, every view's blobs assigned, every track updated, people born, found again,
re-identified and ended.

:meth:`Tracker.step` runs, at the fusion instant, in pipeline order:

1. **Predict** every track to the instant (:class:`~.filter.TrackFilter`, the motion model of :mod:`.motion`).
2. **Expected detections**: what each camera should see of each track: in its picture, in range, not hidden
   behind someone nearer (:func:`~.observe.visibility_many`).
3. **Assign, per view**: how well each blob fits each track (:mod:`.observe`) gives one cost; the blobs are
   assigned one to one to tracks, or left to clutter and new people (Hungarian, scipy's ``linear_sum_assignment``).
   Then again, each view against where the other views' assignments put each track
   (:meth:`~.update.Updater.leave_one_out`): among people close together, the choice the other views agree with,
   kept where those second choices agree with themselves (:func:`_consistent`).
4. **Update** each track with every view assigned to it (:mod:`.update`), its head height, looks and links.
5. **Births and returns** from the blobs no track explains (:mod:`.births`): a new person next to a track no
   view detected is that track found again; the others start tentative (:mod:`.life`).
6. **Existence**: each view that should see a track raises its existence when it detects the person and
   lowers it when it does not (a detection assigned to a track never counts against it), tempered so that a
   view's frames within ``evidence_time_s`` count once, and held below where the person could have left. The views
   of one multi-view detector find or miss a person once, at its recall, learnt from the tracks (:mod:`.recall`).
7. **Prune**: a track ends when its existence is gone, its position is lost (``lost_sigma_m``), its height is no
   person's, its person left the area, or it is another track's person followed twice. A confirmed track that
   ended inside the area is remembered (:class:`~.life.Graveyard`).
8. **Confirm**: a track whose existence reaches ``p_confirm`` is published, under a lost track's id when it is
   that person back, else a new one.

Only this package changes a track; :meth:`Tracker.step` returns what the other stages need, and
:meth:`Tracker.snapshots` what they may read of the tracks.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.sparse import coo_array
from scipy.sparse.csgraph import connected_components

from common.arrays import BoolArray, FloatArray, IntArray
from common.schema import Method, PairEntry, TrackState
from resource_manager.track.births import BirthParams, Hypothesis, find_births
from resource_manager.track.filter import TrackFilter, worst_sigma
from resource_manager.track.life import (
    CLOSE_M,
    PAIR_OF_TRACKS,
    RETURN_CHI2,
    Coverage,
    Graveyard,
    Lost,
    NewTrack,
    Separation,
    at_exit,
    blobs_show_two,
    close_pairs,
    entry_velocity,
    existence_caps,
    left_area,
    match_returns,
    two_people_ln_odds,
)
from resource_manager.track.looks import looks_ln_odds
from resource_manager.track.model import Scene, TrackModel, logit
from resource_manager.track.motion import MotionModel
from resource_manager.track.observe import (
    Looks,
    TrackTable,
    ViewScores,
    Visibility,
    gains_claimed,
    in_any_view,
    score_views,
    visibility_many,
)
from resource_manager.track.recall import SharedRecall, detector_misses
from resource_manager.track.state import TrackRecord
from resource_manager.track.update import Assigned, Tick, Updater
from resource_manager.views.blobs import Views

__all__ = ["TrackSnapshot", "Tracker", "TrackerOutcome"]

PRIOR_SIGMA_M = 1.0
"""Position spread (m) of the prior a new person's first multi-view fix starts from, around the pair's point."""
HEIGHT_SIGMAS = 4.0
"""A track whose head height is surely this many of the population's sigmas from its mean is no person (a false
blob's ray crossing someone's, a robot's body): 1.1-2.3 m with the default 1.7 +- 0.15 m."""
SAME_PERSON_CHI2 = 9.21
"""Two tracks whose positions differ by less than this (Mahalanobis², 2 dof: 99 %) and by less than a person's width
are one person followed twice (a detector's double box, two views' calibrations that disagree), unless some view
has shown them apart (:class:`~.life.Separation`)."""


@dataclass(frozen=True, slots=True)
class TrackSnapshot:
    """What the other stages may read of one track, at the latest tick (a copy: changing it changes nothing)."""

    serial: int
    track_id: str
    """The published id; "" while tentative."""
    x: FloatArray
    """(4,) x, y (m) and vx, vy (m/s) on the floor."""
    p_xy: FloatArray
    """(2, 2) position covariance (m²)."""
    height_m: float
    existence: float
    state: TrackState
    method: Method
    sensors: tuple[str, ...]
    views: tuple[str, ...]
    """The cameras whose blobs placed it at this tick (``sensors`` is the best pair of them)."""
    predicted_error_m: float
    born_ns: int
    t_ns: int
    hits: int
    misses: int
    confirmed: bool
    detected: bool
    """Some view detected the person at this tick."""
    placed: bool
    """Its position is known to within ``publish_sigma_m``."""
    reported: bool
    """Published now: confirmed, more likely there than not, and placed."""

    @property
    def xy(self) -> FloatArray:
        return self.x[:2]


@dataclass(slots=True)
class TrackerOutcome:
    """What one tick did, for the other stages."""

    pair_entries: list[PairEntry] = field(default_factory=list)
    """The best pair (error model) of each detected, confirmed track."""
    ended: list[str] = field(default_factory=list)
    """Ids of the confirmed tracks that ended."""
    births: int = 0
    detected: int = 0
    returned: int = 0
    """Tracks no view detected that a new person's detections found again."""
    reidentified: list[str] = field(default_factory=list)
    """Ids of lost tracks given back to a newly confirmed track (the same person back)."""
    merged: list[tuple[int, int]] = field(default_factory=list)
    """(serial, older serial) of the tracks that ended as another's person followed twice."""


class Tracker:
    """All tracks of one manager.

    Args:
        model: the tracker's model (the ``[tracker]`` table).
        births: how new people are found (Eq. 7).
        new_id: returns the next unique track id (called once per confirmed track that is nobody back).
        scene: the site's area and the cameras' range.
        pair_choice: ``error_model`` (the paper), or ``random``: a baseline the error model is measured against.
    """

    def __init__(
        self,
        model: TrackModel,
        births: BirthParams,
        new_id: Callable[[], str],
        *,
        scene: Scene | None = None,
        pair_choice: str = "error_model",
        seed: int = 0,
    ) -> None:
        self.model = model
        self.birth_params = births
        self.new_id = new_id
        self.scene = scene if scene is not None else Scene()
        self.pair_choice = pair_choice
        self.motion = MotionModel(model.speed_sigma_mps, model.turn_time_s)
        self.filter = TrackFilter(
            self.motion, model.height_change_mps, height_outlier=(model.outlier_prob, model.outlier_scale)
        )
        self.tracks: list[TrackRecord] = []
        """Row for row with :attr:`filter`."""
        self.updater = Updater(model, births.width_rel_sigma, pair_choice, seed)
        self.separation = Separation()
        self.graveyard = Graveyard()
        self.recall = SharedRecall(model)
        """What the sites' multi-view detectors find (:attr:`~resource_manager.views.blobs.Views.shared_detector`)."""
        self._serial = 0
        self._t_ns = 0
        self._tick = 0

    # -- reading --------------------------------------------------------------------------------------
    def snapshots(self) -> list[TrackSnapshot]:
        """Every track as the other stages may read it."""
        f = self.filter
        sigma = f.position_sigma()
        placed, likely = self._shown(sigma)
        existence = f.existence().tolist()
        out = []
        for i, tr in enumerate(self.tracks):
            out.append(
                TrackSnapshot(
                    serial=tr.serial,
                    track_id=tr.track_id,
                    x=f.x[i].copy(),
                    p_xy=f.p[i, :2, :2].copy(),
                    height_m=float(f.height[i]),
                    existence=existence[i],
                    state=tr.state(),
                    method=tr.method,
                    sensors=tr.sensors,
                    views=tr.views,
                    predicted_error_m=tr.predicted_error_m,
                    born_ns=tr.born_ns,
                    t_ns=int(f.t_ns[i]),
                    hits=tr.hits,
                    misses=tr.misses,
                    confirmed=tr.confirmed,
                    detected=tr.detected,
                    placed=bool(placed[i]),
                    reported=tr.confirmed and bool(placed[i] and likely[i]),
                )
            )
        return out

    def _shown(self, sigma: FloatArray) -> tuple[BoolArray, BoolArray]:
        """(n,) each track placed (its position known to within ``publish_sigma_m``) and more likely there than
        not: a confirmed track both is reported."""
        return sigma <= self.model.publish_sigma_m, self.filter.logodds >= 0.0

    # -- the tick -------------------------------------------------------------------------------------
    def adopt(self, names: dict[int, str], followed: dict[int, str] | None = None) -> None:
        """Rename confirmed tracks: serial -> the id to publish them under from now on (a standby following its
        leader, resource_manager/serve/adopt.py). A lost track kept under one of those ids is forgotten: one id,
        one person.

        ``followed``: serial -> the other manager's track each of these follows, one to one (each a different
        person of its set): any two of them are as told apart now, as if a view had shown them as two people, and
        a tentative one is confirmed under that id (if it is free then)."""
        followed = followed or {}
        taken = set()
        for tr in self.tracks:
            new = names.get(tr.serial)
            if new and tr.confirmed:
                tr.track_id = new
                taken.add(new)
            elif not tr.confirmed:
                tr.adopted = followed.get(tr.serial, "")
        self.graveyard.take(taken)
        if len(followed) >= PAIR_OF_TRACKS:
            self.separation.told_apart(followed.keys(), self._t_ns)

    def step(
        self,
        views: Views,
        t_ns: int,
        *,
        blind: frozenset[str] = frozenset(),
        pose_sigma: dict[str, float] | None = None,
    ) -> TrackerOutcome:
        """One tick at instant ``t_ns`` with the views of every camera that can tell something (in order of sensor ids).

        ``blind``: cameras that cannot detect anyone now (a robot driving): their blobs are used, their empty
        places are no evidence that nobody is there.
        """
        dt_s = (t_ns - self._t_ns) / 1e9 if self._t_ns else 0.0
        if t_ns <= self._t_ns:
            return TrackerOutcome()
        self._t_ns = t_ns
        self._tick += 1
        out = TrackerOutcome()
        # 1. Predict.
        self.filter.predict(t_ns)
        # 2. Expected detections.
        sids = views.sensor_ids
        evidence = {sid: self._weights(period, dt_s) for sid, period in zip(sids, views.period_s.tolist(), strict=True)}
        table = self.filter.table()
        vis = visibility_many(views, table, self.model, self.scene.max_range_m)
        vis.p_detect[[i for i, sid in enumerate(sids) if sid in blind]] = 0.0
        tick = Tick(views, evidence, pose_sigma or {}, np.array([evidence[sid][0] for sid in sids]), vis)
        # 3. Assign, per view.
        looks = Looks.of(self.tracks, views, self.model.look_min_s)
        scores = score_views(
            views,
            views.every(),
            self.tracks,
            table,
            vis,
            model=self.model,
            max_range_m=self.scene.max_range_m,
            looks=looks,
        )
        scored = dict(zip(sids, scores, strict=True))
        claim = self._claims()
        assigned = _assign_views(sids, scores, claim)
        # ...and again, each view against where the others put each track: a view's choice among people close
        # together is the one that agrees with the other views (their first choices), not only with the motion.
        # Existence (step 6) reads the first scoring: against the others' place, a view's fit would count their
        # evidence again.
        assigned = _consistent(
            assigned, lambda got, rows: self._against_others(got, tick, table, vis, looks=looks, rows=rows), sids, claim
        )
        # 4. Update.
        predicted = self.filter.x.copy(), self.filter.p.copy()
        updated = self.updater.update(self.filter, self.tracks, assigned, tick, t_ns)
        out.pair_entries = updated.pair_entries
        out.detected = sum(1 for got in updated.kept if got)
        self.filter.mark_seen(np.array([i for i, got in enumerate(updated.kept) if got], dtype=np.int64))
        hits: dict[str, dict[int, int]] = {sid: {} for sid in views.sensor_ids}
        for i, got in enumerate(updated.kept):
            for sid, j in got:
                hits[sid][i] = j
        # 5. Births and returns.
        unexplained = np.ones(views.n, dtype=bool)
        starts = views.offsets.tolist()
        unexplained[[starts[views.rows[sid]] + j for sid, hit in hits.items() for j in hit.values()]] = False
        hyps = self._hypotheses(tick, unexplained, t_ns)
        hyps, returned = self._returns(hyps, tick, t_ns, hits, predicted)
        out.returned = len(returned)
        for i, tr in enumerate(self.tracks):
            tr.views = tuple(sid for sid in sids if i in hits[sid])
        # 6. Existence (of the tracks there were; new ones start from their own evidence).
        coverage = self._coverage(views)
        exits = at_exit(self.filter.x[:, :2], self.filter.position_sigma(), self.model, self.scene, coverage)
        self._existence(scored, hits, tick, existence_caps(exits, self.model, self.scene), dt_s)
        out.births = self._spawn(hyps, tick, t_ns)
        self._note_apart(hits, scored, tick, t_ns)
        # 7. Prune, 8. confirm.
        out.ended = self._prune(t_ns, coverage, out.merged)
        out.reidentified = self._confirm(t_ns)
        return out

    def _against_others(
        self,
        assigned: list[list[Assigned]],
        tick: Tick,
        table: TrackTable,
        vis: Visibility,
        *,
        looks: Looks,
        rows: IntArray | None,
    ) -> list[ViewScores]:
        """Each view's blobs against where the other views' ``assigned`` blobs put each track (only the tracks of
        filter ``rows``, in that order, if given)."""
        xy, cov = self.updater.leave_one_out(self.filter, assigned, tick)
        tracks = self.tracks
        others = TrackTable(xy, cov, table.height, table.height_var)
        if rows is not None:
            tracks = [tracks[i] for i in rows.tolist()]
            others = TrackTable(xy[:, rows], cov[:, rows], table.height[rows], table.height_var[rows])
            vis = Visibility(*(part[:, rows] for part in vis))
            looks = looks.take(rows)
        return score_views(
            tick.views,
            tick.views.every(),
            tracks,
            others,
            vis,
            model=self.model,
            max_range_m=self.scene.max_range_m,
            looks=looks,
        )

    def _claims(self) -> FloatArray:
        """(n,) how surely each track is someone, as the assignment weighs its claim to a blob: a tentative track
        is a person only as likely as its existence says (it may be a false detection's echo, or someone already
        followed); a published one is a person."""
        confirmed = np.array([tr.confirmed for tr in self.tracks], dtype=bool)
        return np.where(confirmed, 1.0, self.filter.existence())

    def _weights(self, period_s: float, dt_s: float) -> tuple[float, float]:
        """(position, existence) weight at this tick of the evidence of a view whose frames come every ``period_s``
        (0: unknown).

        A tick between two frames sees an interpolation of frames already used: it carries ``dt / period`` of a
        frame's information. Existence moves at most one view's worth per ``evidence_time_s``.
        """
        period = period_s if period_s > 0 else dt_s
        if dt_s <= 0:  # the first tick: one frame's worth
            dt_s = period if period > 0 else self.model.evidence_time_s
        w_pos = min(1.0, dt_s / period) if period > 0 else 1.0
        w_exist = min(w_pos, dt_s / self.model.evidence_time_s, 1.0)
        return max(w_pos, 1e-3), w_exist

    def _coverage(self, views: Views) -> Coverage:
        """Where the cameras of this tick see a person of the usual height (their joint view)."""
        return lambda xy: in_any_view(views, xy, self.model.height_prior_m, self.scene.max_range_m)

    def _existence(
        self,
        scored: dict[str, ViewScores],
        hits: dict[str, dict[int, int]],
        tick: Tick,
        caps: FloatArray,
        dt_s: float,
    ) -> None:
        """Raise the existence of the tracks each view detects (``hits``: per view, track -> blob), lower that of
        those it should see but misses; view after view in order of sensor ids, each held below ``caps`` (where
        the track's person could have left: :func:`~.life.existence_caps`). The multi-view detectors learn their
        recall from it (:attr:`recall`; ``dt_s`` since the last tick)."""
        n = len(self.tracks)
        if not n:
            return
        views = list(scored.values())
        p_detect = np.array([sc.p_detect for sc in views]).reshape(-1, n)
        groups = tick.views.shared_groups
        sure = self._sure(n) if groups else None  # before this tick's evidence
        # (view, track) ln of the likelihood ratio of detected against missed, of each view's evidence.
        delta = np.array([sc.ln_miss for sc in views]).reshape(-1, n)
        hit = [(v, i, j) for v, sid in enumerate(scored) for i, j in hits[sid].items()]
        got = np.zeros(delta.shape, dtype=bool)
        if hit:
            rows, cols = np.array([h[0] for h in hit]), np.array([h[1] for h in hit])
            got[rows, cols] = True
            ln_lr = np.array([views[h[0]].ln_lr[h[1], h[2]] if h[2] >= 0 else -np.inf for h in hit])
            lr = np.log(1.0 - p_detect[rows, cols] + np.exp(np.minimum(ln_lr, 50.0)))
            delta[rows, cols] = np.maximum(lr, 0.0)  # a detection assigned to a track never counts against it
            # A view that detected a track it did not expect to see (a return) counts as seeing it.
            p_detect[rows, cols] = np.maximum(p_detect[rows, cols], 1e-6)
        sees = p_detect > 0
        if groups:
            self._one_miss_per_detector(delta, sees, got, groups)
        weight = np.array([tick.weights[sid][1] for sid in scored])
        self.filter.existence_update(delta, weight, sees, caps)
        if sure is not None:
            serials = [tr.serial for tr in self.tracks[:n]]
            self.recall.learn(groups, sees, got, sure=sure, serials=serials, dt_s=dt_s)

    def _one_miss_per_detector(
        self, delta: FloatArray, sees: BoolArray, got: BoolArray, groups: Mapping[str, IntArray]
    ) -> None:
        """Count the views of each multi-view detector (``groups``: its name -> its view rows) as that one detector in
        ``delta`` (s, n), each view's ln likelihood ratio for each track (in place, :func:`~.recall.detector_misses`):
        a track some of its views detected is not missed by the others; one none did is missed once, at ln(1 - its
        learnt recall). ``sees``, ``got``: (s, n) which views should see and which detected each track."""
        for name, rows in groups.items():
            hit, block = got[rows], delta[rows]
            once = np.full(block.shape[1], math.log1p(-self.recall.recall(name)))
            misses = detector_misses(np.where(sees[rows] & ~hit, block, 0.0), hit, once)
            delta[rows] = np.where(hit, block, misses)

    def _sure(self, n: int) -> BoolArray:
        """(n,) which of the first ``n`` tracks surely are someone: published, placed and more likely there than not."""
        placed, likely = self._shown(self.filter.position_sigma()[:n])
        return np.array([tr.confirmed for tr in self.tracks[:n]], dtype=bool) & placed & likely[:n]

    # -- births and returns ---------------------------------------------------------------------------
    def _hypotheses(self, tick: Tick, unexplained: BoolArray, t_ns: int) -> list[Hypothesis]:
        """New people among the unexplained blobs (``unexplained``: (m,) over the tick's blobs); nobody next to a
        track a view detected. One where a track that a multi-view detector's misses just ended would be shows those
        were misses of someone there (:meth:`~.recall.SharedRecall.found`)."""
        m = self.model
        w = min((we for _, we in tick.weights.values()), default=1.0)
        if w <= 0:
            return []
        # Started only where the evidence, tempered like every update, lifts it above the deletion threshold.
        need = (logit(m.p_delete) - logit(m.p_birth)) / w
        detected = np.array([i for i, tr in enumerate(self.tracks) if tr.detected], dtype=np.int64)
        hyps = find_births(
            tick.views,
            unexplained,
            self.filter.table(detected),
            m,
            scene=self.scene,
            params=self.birth_params,
            tick=self._tick,
            min_evidence=need,
        )
        if hyps:
            fixes = np.array([h.fix.xy for h in hyps]), np.array([h.fix.cov for h in hyps])
            self.recall.found(*fixes, t_ns, self.motion)
        return hyps

    def _returns(
        self,
        hyps: list[Hypothesis],
        tick: Tick,
        t_ns: int,
        hits: dict[str, dict[int, int]],
        predicted: tuple[FloatArray, FloatArray],
    ) -> tuple[list[Hypothesis], list[int]]:
        """New people where a track is predicted, that no view detected this tick (coasting) or whose blobs pulled
        it far from where it was predicted (it jumped onto someone else's, or a false blob), are that track found
        again: it is updated, from its prediction (``predicted``: every row's state and covariance before this
        tick's update), with the hypothesis' blobs instead. Returns the hypotheses left (new people) and the rows
        found again; ``hits`` follows.

        A coasting track less likely there than not has lost its person (they left unseen, or were never there):
        someone new where it is predicted, however vague, starts a track of their own (if they are that person
        back, re-identification gives the id back once the lost track has ended)."""
        f = self.filter
        x0, p0 = predicted
        n = len(x0)
        moved = f.x[:n, :2] - x0[:, :2]
        jumped = np.einsum("ni,nij,nj->n", moved, np.linalg.inv(p0[:, :2, :2]), moved) > RETURN_CHI2 if n else []
        likely = f.logodds[:n] >= 0.0
        rows = [
            i
            for i in range(n)
            if (self.tracks[i].state() == "coasting" and likely[i]) or (self.tracks[i].confirmed and jumped[i])
        ]
        if not hyps or not rows:
            return hyps, []
        cand = np.array(rows, dtype=np.int64)
        pairs = match_returns(
            np.array([h.fix.xy for h in hyps]), np.array([h.fix.cov for h in hyps]), x0[cand, :2], p0[cand, :2, :2]
        )
        if not pairs:
            return hyps, []
        back = np.array([cand[b] for _, b in pairs], dtype=np.int64)
        gots = [[Assigned(s, j) for s, j in sorted(hyps[a].blobs.items())] for a, _ in pairs]
        f.x[back], f.p[back] = x0[back], p0[back]
        for hit in hits.values():  # the blobs it jumped to go back to the unexplained ones
            for row in back.tolist():
                hit.pop(row, None)
        self.updater.fuse(f, back, gots, tick, lines=False)
        f.fuse_heights(back, gots, tick.views)
        f.mark_seen(back)
        for row, got in zip(back.tolist(), gots, strict=True):
            tr = self.tracks[row]
            if not tr.detected:
                tr.hits += 1
            tr.detected, tr.misses, tr.seen_ns, tr.method = True, 0, t_ns, "least_squares"
            for sid, j in got:
                hits[sid][row] = j
        self.updater.learn(
            [(self.tracks[r], {a.sensor_id: a.blob for a in g}, 1.0) for r, g in zip(back.tolist(), gots, strict=True)],
            tick.views,
        )
        used = {a for a, _ in pairs}
        return [h for k, h in enumerate(hyps) if k not in used], back.tolist()

    def _spawn(self, hyps: list[Hypothesis], tick: Tick, t_ns: int) -> int:
        """Start a tentative track on each new person (existence: the prior and its evidence): at its best pair's
        fix (``paper`` mode) or updated from a wide prior there with all its views (all at once)."""
        if not hyps:
            return 0
        m = self.model
        w = min((we for _, we in tick.weights.values()), default=1.0)
        logodds = [min(logit(m.p_birth) + w * h.evidence, logit(m.p_max)) for h in hyps]
        gots = [[Assigned(s, j) for s, j in sorted(h.blobs.items())] for h in hyps]
        xs = np.array([[h.fix.xy[0], h.fix.xy[1], 0.0, 0.0] for h in hyps])
        priors = np.repeat(np.diag([PRIOR_SIGMA_M**2, PRIOR_SIGMA_M**2, 0.0, 0.0])[None], len(hyps), axis=0)
        sigma = worst_sigma(np.array([h.fix.cov for h in hyps]).reshape(-1, 2, 2))
        # At the first tick nobody was looked for before: who stands by an exit may as well be leaving.
        v_mean, v_cov = entry_velocity(xs[:, :2], sigma, m, self.scene if self._tick > 1 else Scene())
        xs[:, 2:], priors[:, 2:, 2:] = v_mean, v_cov
        bests = [r.best for r in self.updater.rank_many(xs[:, :2], [sorted(h.blobs) for h in hyps], tick)]
        first = self.filter.n
        self.filter.add(
            xs,
            priors,
            height=np.full(len(hyps), m.height_prior_m),
            height_var=np.full(len(hyps), m.height_sigma_m**2),
            logodds=np.array(logodds),
            t_ns=t_ns,
        )
        rows = np.arange(first, first + len(hyps), dtype=np.int64)
        fixes = [
            self.updater.pair_fix(best, h.blobs, tick) if m.mode == "paper" and best is not None else None
            for h, best in zip(hyps, bests, strict=True)
        ]
        fused = [k for k, fix in enumerate(fixes) if fix is None]
        if fused:
            self.updater.fuse(self.filter, rows[fused], [gots[k] for k in fused], tick, lines=False)
        born: list[TrackRecord] = []
        for k, (fix, best) in enumerate(zip(fixes, bests, strict=True)):
            if fix is not None:
                self.filter.p[rows[k], :2, :2] = fix.cov
                self.filter.x[rows[k], :2] = fix.xy
            self._serial += 1
            tr = TrackRecord(
                serial=self._serial,
                born_ns=t_ns,
                first_xy=self.filter.x[rows[k], :2].copy(),
                detected=True,
                seen_ns=t_ns,
                hits=1,
                method=fix.method if fix is not None else "least_squares",
            )
            if best is not None:
                tr.sensors = (best.a, best.b)
                tr.predicted_error_m = best.error_m
            tr.views = tuple(sorted(hyps[k].blobs))
            born.append(tr)
        self.tracks.extend(born)
        self.filter.fuse_heights(rows, gots, tick.views)
        self.filter.mark_seen(rows)
        self.updater.learn(
            [(tr, h.blobs, min(tick.weights[s][0] for s in h.blobs)) for tr, h in zip(born, hyps, strict=True)],
            tick.views,
        )
        return len(hyps)

    def _note_apart(
        self, hits: dict[str, dict[int, int]], scored: dict[str, ViewScores], tick: Tick, t_ns: int
    ) -> None:
        """What each view says, this tick, of every two close tracks being two people or one followed twice
        (:class:`~.life.Separation`): ``hits`` per view, track row -> blob; ``scored`` each view's chance of
        detecting each track there was before this tick's births (new tracks say nothing yet)."""
        f, views = self.filter, tick.views
        evidence: dict[tuple[int, int], float] = {}
        scored_rows = min((len(sc.p_detect) for sc in scored.values()), default=0)
        if scored_rows >= PAIR_OF_TRACKS:
            xy = f.x[:scored_rows, :2]
            close, _ = close_pairs(xy)
            if len(close):
                a, b = close[:, 0], close[:, 1]
                order = [views.rows[sid] for sid in hits]
                # Each view's blob of each track (-1: none), and what each view should have seen of each.
                blob = np.full((views.n_views, scored_rows), -1, dtype=np.int64)
                for row, hit in zip(order, hits.values(), strict=True):
                    known = [i for i in hit if i < scored_rows]
                    blob[row, known] = [hit[i] for i in known]
                p = np.zeros((views.n_views, scored_rows))
                p[order] = [scored[sid].p_detect[:scored_rows] for sid in hits]
                got_a, got_b = blob[:, a] >= 0, blob[:, b] >= 0
                # Two blobs, one given to each, that do not show two people say nothing either way.
                v, k = np.nonzero(got_a & got_b)
                ea, eb = views.offsets[v] + blob[v, a[k]], views.offsets[v] + blob[v, b[k]]
                d = xy[None, :, :] - views.origin[:, None, :]
                bearing = np.arctan2(d[:, :, 1], d[:, :, 0])
                unsure = np.zeros(got_a.shape, dtype=bool)
                unsure[v, k] = ~blobs_show_two(
                    (bearing[v, a[k]], bearing[v, b[k]]),
                    (views.bearing_rad[ea], views.bearing_rad[eb]),
                    (views.width_rad[ea], views.width_rad[eb]),
                )
                ln = np.where(unsure, 0.0, two_people_ln_odds(p[:, a], p[:, b], got_a, got_b))
                total = np.zeros(len(close))
                for sid, row in zip(hits, order, strict=True):
                    total += tick.weights[sid][1] * ln[row]
                evidence = dict(zip(zip(a.tolist(), b.tolist(), strict=True), total.tolist(), strict=True))
        self.separation.note([tr.serial for tr in self.tracks], f.x[:, :2], evidence, t_ns)

    # -- ends and ids ---------------------------------------------------------------------------------
    def _prune(self, t_ns: int, coverage: Coverage, merged: list[tuple[int, int]]) -> list[str]:
        """End the tracks whose existence is gone, whose position is lost, whose height is no person's, whose
        person left the area, or that follow another track's person (the one reported now keeps its id, else the
        older). Confirmed tracks that ended inside the area, not at an exit, are remembered for
        re-identification, those taken for another's person followed twice too: two people whom every view showed
        as one blob for a while are one track until they part, and the one who walks off is a lost person back."""
        m, f = self.model, self.filter
        if not self.tracks:
            return []
        delete = logit(m.p_delete)
        sigma = f.position_sigma()
        out_of_area = left_area(f.x[:, :2], sigma, self.scene)
        exits = at_exit(f.x[:, :2], sigma, m, self.scene, coverage)
        keep: list[int] = []
        ended: list[str] = []
        # Surest first: a confirmed track before a tentative one, one reported now (there and placed) before one
        # that is not (its person lost: it may not take the id of the track that follows them now), then the oldest.
        shown = np.logical_and(*self._shown(sigma))
        surest = sorted(
            range(len(self.tracks)), key=lambda r: (not self.tracks[r].confirmed, not shown[r], self.tracks[r].serial)
        )
        # Pairs plainly farther apart than CLOSE_M (with a margin for np.hypot against math.hypot) are no person
        # followed twice (:meth:`_one_spot`'s first test): left out at once instead of pair by pair.
        d = f.x[:, None, :2] - f.x[None, :, :2]
        maybe_close = (~(np.hypot(d[..., 0], d[..., 1]) >= CLOSE_M * (1.0 + 1e-9))).tolist()
        for i in surest:
            tr = self.tracks[i]
            lost = float(f.logodds[i]) < delete or float(sigma[i]) > m.lost_sigma_m
            twice = next((k for k in keep if maybe_close[i][k] and self._same_person(i, k, t_ns)), None)
            if not (lost or twice is not None or out_of_area[i] or self._implausible_height(i)):
                keep.append(i)
                continue
            if twice is not None:
                merged.append((tr.serial, self.tracks[twice].serial))
            elif float(f.logodds[i]) < delete:
                self.recall.ended(tr.serial, f.x[i], f.p[i], t_ns)
            if tr.track_id:
                ended.append(tr.track_id)
                if (lost or twice is not None) and not exits[i] and m.reid_window_s > 0:
                    self.graveyard.remember(self._lost(i, t_ns))
        keep.sort()
        self.tracks = [self.tracks[i] for i in keep]
        f.keep(np.array(keep, dtype=np.int64))
        self.graveyard.forget_before(t_ns - int(m.reid_window_s * 1e9))
        return ended

    def _lost(self, i: int, t_ns: int) -> Lost:
        tr, f = self.tracks[i], self.filter
        return Lost(
            track_id=tr.track_id,
            ended_ns=t_ns,
            seen_ns=tr.seen_ns,
            x=f.seen_x[i].copy(),
            p=f.seen_p[i].copy(),
            height_m=float(f.height[i]),
            height_var=float(f.height_var[i]),
            looks=dict(tr.looks),
            look_s=dict(tr.look_s),
            serial=tr.serial,
        )

    def _same_person(self, i: int, k: int, t_ns: int) -> bool:
        """Whether track ``i`` is track ``k``'s person followed twice: :meth:`_one_spot`, and, both published, for
        long enough: together, never told apart, for ``evidence_time_s``, or ``apart_time_s`` if some view has
        shown them as two people."""
        if not self._one_spot(i, k, t_ns):
            return False
        a, b = self.tracks[i], self.tracks[k]
        if not (a.confirmed and b.confirmed):
            return True
        since_apart = self.separation.since_apart_s(a.serial, b.serial, t_ns)
        need = self.model.evidence_time_s if math.isinf(since_apart) else self.model.apart_time_s
        together = min(self.separation.together_s(a.serial, b.serial, t_ns), since_apart)
        return together >= need - 1e-9

    def _one_spot(self, i: int, k: int, t_ns: int) -> bool:
        """Whether track ``i`` stands where only one person fits beside track ``k``, their estimates agree that
        they are one, no view has shown them apart for ``evidence_time_s`` and, both published, they move alike
        (two published people who meet are likelier two people passing than one followed twice: one person's two
        tracks share a velocity; people who cross do not)."""
        f = self.filter
        dx, dy = float(f.x[i, 0] - f.x[k, 0]), float(f.x[i, 1] - f.x[k, 1])
        if math.hypot(dx, dy) >= CLOSE_M:
            return False
        s = f.p[i, :2, :2] + f.p[k, :2, :2]
        det = float(s[0, 0] * s[1, 1] - s[0, 1] * s[1, 0])
        if det > 0:
            d2 = (float(s[1, 1]) * dx * dx - 2.0 * float(s[0, 1]) * dx * dy + float(s[0, 0]) * dy * dy) / det
            if d2 >= SAME_PERSON_CHI2:
                return False
        a, b = self.tracks[i], self.tracks[k]
        if self.separation.since_apart_s(a.serial, b.serial, t_ns) < self.model.evidence_time_s - 1e-9:
            return False
        if not (a.confirmed and b.confirmed):
            return True
        dv = f.x[i, 2:] - f.x[k, 2:]
        sv = f.p[i, 2:, 2:] + f.p[k, 2:, 2:]
        return float(dv @ np.linalg.solve(sv, dv)) < SAME_PERSON_CHI2

    def _implausible_height(self, i: int) -> bool:
        """Whether the track's measured head height rules out a person (the height prior, Eq. 7's r_hc in
        absolute)."""
        m, f = self.model, self.filter
        spread = math.sqrt(m.height_sigma_m**2 + float(f.height_var[i]))
        return abs(float(f.height[i]) - m.height_prior_m) > HEIGHT_SIGMAS * spread

    def _confirm(self, t_ns: int) -> list[str]:
        """Publish the tracks whose existence reached ``p_confirm``: the id another manager publishes the person
        under (:meth:`adopt`), else a lost one's id when it is that person back (:meth:`~.life.Graveyard.match`),
        else a new id. Returns the ids given back."""
        m, f = self.model, self.filter
        rows = [i for i, tr in enumerate(self.tracks) if not tr.confirmed and float(f.logodds[i]) >= logit(m.p_confirm)]
        if not rows:
            return []
        new = [
            NewTrack(
                born_ns=self.tracks[i].born_ns,
                first_xy=self.tracks[i].first_xy,
                height_m=float(f.height[i]),
                height_var=float(f.height_var[i]),
                looks=self.tracks[i].looks,
                look_s=self.tracks[i].look_s,
            )
            for i in rows
        ]

        def colour(
            a: dict[str, FloatArray], a_s: dict[str, float], b: dict[str, FloatArray], b_s: dict[str, float]
        ) -> float | None:
            return looks_ln_odds(a, a_s, b, b_s, sigma=m.colour_sigma, outlier_prob=m.outlier_prob, min_s=m.look_min_s)

        area_m2 = self.scene.area.area_m2 if self.scene.area is not None else None
        others = np.array([i for i in range(len(self.tracks)) if i not in set(rows)], dtype=np.int64)
        back = dict(
            self.graveyard.match(new, f.x[others, :2], model=m, motion=self.motion, colour_ln=colour, area_m2=area_m2)
        )
        # An id another manager's track of the person has (a standby's leader's) before one given back.
        in_use = {tr.track_id for tr in self.tracks if tr.track_id}
        pending = [self.tracks[i].adopted for i in rows]
        adopted = {k: tid for k, tid in enumerate(pending) if tid and tid not in in_use and pending.count(tid) == 1}
        back = {k: g for k, g in back.items() if k not in adopted and g.track_id not in adopted.values()}
        for k, i in enumerate(rows):
            tr = self.tracks[i]
            tr.confirmed = True
            if k in adopted:
                tr.track_id = adopted[k]
            elif k in back:
                tr.track_id = back[k].track_id
                for sid, look in back[k].looks.items():
                    if sid not in tr.looks:
                        tr.looks[sid], tr.look_s[sid] = look, back[k].look_s.get(sid, 0.0)
            else:
                tr.track_id = self.new_id()
        ids = [g.track_id for g in back.values()]
        self.graveyard.take(set(ids) | set(adopted.values()))
        return ids


def _assign_views(sids: tuple[str, ...], scores: list[ViewScores], claim: FloatArray) -> list[list[Assigned]]:
    """Each track's blobs, one view at a time: in each view, the one-to-one (track, blob) pairs of positive gain
    that maximise the total gain (Hungarian), each track's claim weighed by how surely it is someone (``claim``:
    (n,); :meth:`~.observe.ViewScores.gain_claimed`).

    The gains and which of them count are worked out for every view at once (the views' blobs side by side: a
    tick has many views of a few blobs each, where numpy's cost per call outweighs its arithmetic); only the
    Hungarian step runs view by view."""
    out: list[list[Assigned]] = [[] for _ in range(len(claim))]
    counts = [sc.ln_lr.shape[1] for sc in scores]
    if not len(claim) or not sum(counts):
        return out
    gain = gains_claimed(scores, claim)
    ok = np.isfinite(gain) & (gain > 0)
    starts = np.cumsum([0, *counts])
    so_far = np.concatenate([np.zeros((len(claim), 1), dtype=np.int64), np.cumsum(ok, axis=1)], axis=1)
    # [i, v]: track i has a blob worth taking in view v; [e]: blob e is worth taking for some track.
    row_ok = so_far[:, starts[1:]] > so_far[:, starts[:-1]]
    col_ok = np.asarray(ok.any(axis=0), dtype=bool)
    positive = np.where(ok, gain, 0.0)
    bounds = starts.tolist()
    for v in np.flatnonzero(row_ok.any(axis=0)).tolist():
        a, b = bounds[v], bounds[v + 1]
        rows, cols = row_ok[:, v].nonzero()[0], col_ok[a:b].nonzero()[0]
        sub = positive[rows[:, None], cols + a]
        r, c = linear_sum_assignment(sub, maximize=True)
        keep = sub[r, c] > 0
        sid = sids[v]
        for i, j in zip(rows[r[keep]].tolist(), cols[c[keep]].tolist(), strict=True):
            out[i].append(Assigned(sid, j))
    return out


def _consistent(
    first: list[list[Assigned]],
    against_others: Callable[[list[list[Assigned]], IntArray | None], list[ViewScores]],
    sids: tuple[str, ...],
    claim: FloatArray,
) -> list[list[Assigned]]:
    """The second pass: each view's blobs assigned again against where the other views' ``first`` choices put each
    track (``against_others``), where the new choices agree with themselves; else the first choices.

    Each view's second choice relies on the *first* choices of the other views. Where several views change their
    minds about the same people at once, each relies on a choice another no longer makes: two cameras at the two
    ends of one line of sight through two people, each seeing only the nearer one, each give their blob to the
    other camera's track, and the tracks swap. So the tracks whose blobs changed are grouped (the tracks one view's
    change touches, one group), and each group keeps the pass whose choices fit each other better: the sum, over
    each track's blobs, of the blob's gain against where that pass's other blobs of the track put it
    (``against_others``), the pseudo-likelihood of each pass's assignment.
    """
    again = against_others(first, None)
    second = _assign_views(sids, again, claim)
    n = len(first)
    before = [{a.sensor_id: a.blob for a in got} for got in first]
    after = [{a.sensor_id: a.blob for a in got} for got in second]
    links: list[tuple[int, int]] = []
    touched: set[int] = set()
    for sid in sids:
        moved = [i for i in range(n) if before[i].get(sid) != after[i].get(sid)]
        touched.update(moved)
        links += [(moved[0], i) for i in moved]
    if not touched:
        return second
    a, b = np.array(links, dtype=np.int64).T
    _, group = connected_components(coo_array((np.ones(len(a)), (a, b)), shape=(n, n)), directed=False)
    view = {sid: v for v, sid in enumerate(sids)}
    rows = np.array(sorted(touched), dtype=np.int64)
    # Only the touched tracks' places and scores are needed again.
    gain_first = [sc.gain_claimed(claim)[rows] for sc in again]
    alone = [got if i in touched else [] for i, got in enumerate(second)]
    gain_second = [sc.gain_claimed(claim[rows]) for sc in against_others(alone, rows)]
    fit = np.zeros((2, n))  # each group's fit under the first and under the second choices (-inf: a blob off)
    for k, i in enumerate(rows.tolist()):
        fit[0, group[i]] += sum(float(gain_first[view[s]][k, j]) for s, j in before[i].items())
        fit[1, group[i]] += sum(float(gain_second[view[s]][k, j]) for s, j in after[i].items())
    return [second[i] if i not in touched or fit[1, group[i]] > fit[0, group[i]] else first[i] for i in range(n)]
