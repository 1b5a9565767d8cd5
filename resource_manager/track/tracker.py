"""The tracker: every track predicted, every view's blobs assigned, every track updated, people born and ended.

Each tick, at the fusion instant:

1. **Predict** every track to the instant (:mod:`.motion`).
2. **Assign, per view**: what the camera should see of each track (in its picture, not hidden) and how well each
   of its blobs fits each track (:mod:`.observe`) give one cost; the blobs are assigned one to one to tracks, or
   left to clutter and new people (Hungarian, scipy's ``linear_sum_assignment``).
3. **Update** each track with every view assigned to it, each with its own covariance (``model`` mode), or with
   the pair of them the error model ranks best, by Eq. (1) or Eq. (2) (``paper`` mode). Head height, colour
   looks and the nodes' 2D track ids follow.
4. **Existence**: each view that should see a track raises its existence probability when it detects the person
   and lowers it when it does not, by the likelihood ratio of step 2, tempered so that a view's frames within
   ``evidence_time_s`` count once.
5. **Births** from the blobs no track explains (:mod:`.births`).
6. **Life cycle**: a track is confirmed (published, given an id) once its existence reaches ``p_confirm``, and ends
   when it falls below ``p_delete`` or its position is lost (``lost_sigma_m``).

Each step works on every track and view of the tick at once, on arrays (the views stacked, :mod:`.stack`; the
tracks' updates, :mod:`.fuse`): a tick's cost is then a few hundred array operations, not a few dozen per track and
per view. Only the assignment (one Hungarian problem per view) and the pair report (one fix per track) stay loops.

Only this package changes a track's state; :meth:`Tracker.step` returns what the other stages need.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
import numpy.typing as npt
from scipy.optimize import linear_sum_assignment

from common.schema import Method, PairEntry
from resource_manager.stereo.localize import Measurement, localize_best_pair
from resource_manager.stereo.pairs import PairCandidate, rank_pairs_many
from resource_manager.track.births import BirthParams, Hypothesis, find_births
from resource_manager.track.fuse import Slots, fuse, fuse_heights
from resource_manager.track.looks import learn_looks
from resource_manager.track.model import PERSON_RADIUS_M, TrackModel, logit
from resource_manager.track.motion import MotionModel, predict_many
from resource_manager.track.observe import (
    Spread,
    TrackTable,
    ViewScores,
    ViewStack,
    score_views,
    visibility_many,
)
from resource_manager.track.state import TrackRecord
from resource_manager.views.blobs import ViewBlobs

__all__ = ["Tracker", "TrackerOutcome"]

FloatArray = npt.NDArray[np.float64]
MAX_PAIR_CAMERAS = 5
"""Only the cameras nearest a person are paired when ranking pairs by the error model (5 cameras: 10 pairs)."""


@dataclass(slots=True)
class TrackerOutcome:
    """What one tick did, for the other stages."""

    pair_entries: list[PairEntry] = field(default_factory=list)
    """The best pair (error model) of each detected, confirmed track."""
    ended: list[str] = field(default_factory=list)
    """Ids of the confirmed tracks that ended."""
    births: int = 0
    detected: int = 0


@dataclass(frozen=True, slots=True)
class _Tick:
    """What every stage of one tick reads: the views, their evidence weights, the cameras' position errors."""

    views: dict[str, ViewBlobs]
    weights: dict[str, tuple[float, float]]
    """sensor id -> (position, existence) weight of its evidence at this tick (:meth:`Tracker._weights`)."""
    pose_sigma: dict[str, float]
    stack: ViewStack
    """The views stacked into arrays, in order of sensor ids."""
    position_weight: FloatArray
    """(s,) the position weight of each view of ``stack``."""


class _Ranking(NamedTuple):
    """The pair of a track's cameras chosen (:meth:`Tracker._rank`) among how many."""

    best: PairCandidate | None
    candidates: int


class _Assigned(NamedTuple):
    """One view's blob assigned to a track."""

    sensor_id: str
    blob: int


class Tracker:
    """All tracks of one manager.

    Args:
        model: the tracker's model (:class:`~resource_manager.track.model.TrackModel`).
        births: how new people are found (Eq. 7).
        new_id: returns the next unique track id (called once per confirmed track).
        pair_choice: ``error_model`` (the paper), or ``random``: a baseline the error model is measured against.
    """

    def __init__(
        self,
        model: TrackModel,
        births: BirthParams,
        new_id: Callable[[], str],
        *,
        pair_choice: str = "error_model",
        seed: int = 0,
    ) -> None:
        self.model = model
        self.birth_params = births
        self.new_id = new_id
        self.pair_choice = pair_choice
        self.motion = MotionModel(model.speed_sigma_mps, model.turn_time_s)
        self.tracks: list[TrackRecord] = []
        self._serial = 0
        self._t_ns = 0
        self._tick = 0
        self._rng = np.random.default_rng(seed)

    def reported(self, tr: TrackRecord) -> bool:
        """Whether the manager reports ``tr`` now: published (confirmed, more likely there than not) and placed to
        within ``publish_sigma_m``; a vaguer one is held, with its id, until its views pin it down again."""
        return tr.published and tr.position_sigma_m <= self.model.publish_sigma_m

    # -- the tick -------------------------------------------------------------------------------------
    def step(
        self,
        views: dict[str, ViewBlobs],
        t_ns: int,
        *,
        blind: frozenset[str] = frozenset(),
        pose_sigma: dict[str, float] | None = None,
    ) -> TrackerOutcome:
        """One tick at instant ``t_ns`` with the views of every camera that can tell something.

        ``blind``: cameras that cannot detect anyone now (a robot driving): their blobs are used, their empty
        places are no evidence that nobody is there.
        """
        dt_s = (t_ns - self._t_ns) / 1e9 if self._t_ns else 0.0
        if t_ns <= self._t_ns:
            return TrackerOutcome()
        self._t_ns = t_ns
        self._tick += 1
        out = TrackerOutcome()
        self._predict(t_ns)
        table = TrackTable.of(self.tracks)
        evidence = {sid: self._weights(v, dt_s) for sid, v in views.items()}
        sids = sorted(views)
        stack = ViewStack.of([views[sid] for sid in sids], [self._spread(views[sid]) for sid in sids])
        tick = _Tick(views, evidence, pose_sigma or {}, stack, np.array([evidence[sid][0] for sid in sids]))
        pd = visibility_many(stack, table, self.model)
        pd[[i for i, sid in enumerate(sids) if sid in blind]] = 0.0
        scored = dict(zip(sids, score_views(stack, self.tracks, table, pd, model=self.model), strict=True))
        assigned: list[list[_Assigned]] = [[] for _ in self.tracks]
        for sid, scores in scored.items():
            for i, j in _assign(scores):
                assigned[i].append(_Assigned(sid, j))
        kept = self._update_all(assigned, tick, out)
        hits: dict[str, dict[int, int]] = {sid: {} for sid in views}
        for i, got in enumerate(kept):
            for sid, j in got:
                hits[sid][i] = j
        self._existence(scored, hits, tick)
        taken = {sid: set(hit.values()) for sid, hit in hits.items()}
        free = {sid: [j for j in range(views[sid].n) if j not in taken[sid]] for sid in scored}
        out.births = self._births(tick, free, t_ns)
        out.ended = self._prune()
        return out

    def _predict(self, t_ns: int) -> None:
        """Every track predicted to the instant ``t_ns`` (all at once)."""
        if not self.tracks:
            return
        gaps_s = [(t_ns - tr.t_ns) / 1e9 for tr in self.tracks]
        xs, ps = predict_many(
            np.array([tr.x for tr in self.tracks]),
            np.array([tr.p for tr in self.tracks]),
            np.array(gaps_s),
            self.motion,
        )
        for tr, x, p, gap_s in zip(self.tracks, xs, ps, gaps_s, strict=True):
            tr.x, tr.p = x, p
            tr.height_var += self.model.height_change_mps**2 * max(gap_s, 0.0)
            tr.t_ns = t_ns

    def _update_all(self, assigned: list[list[_Assigned]], tick: _Tick, out: TrackerOutcome) -> list[list[_Assigned]]:
        """Update every track with the blobs assigned to it (:meth:`_update`); returns those each keeps.

        In ``model`` mode the tracks' filters are updated all at once (:meth:`_fuse_tracks`) and the pairs of the
        cameras that detected each are ranked all at once; then each track's pair is reported, and its head height,
        looks and links learnt (all tracks at once).
        """
        fused = [i for i, got in enumerate(assigned) if got] if self.model.mode == "model" else []
        weights = self._fuse_tracks([self.tracks[i] for i in fused], [assigned[i] for i in fused], tick)
        weight_of = dict(zip(fused, weights, strict=True))
        kept: list[list[_Assigned]] = []
        rankings: list[_Ranking | None] = []
        for i, (tr, got) in enumerate(zip(self.tracks, assigned, strict=True)):
            keep, ranking = self._update(tr, got, tick, out, weight_of.get(i))
            kept.append(keep)
            rankings.append(ranking)
        later = [i for i, (got, r) in enumerate(zip(kept, rankings, strict=True)) if got and r is None]
        xys = np.array([self.tracks[i].x[:2] for i in later]).reshape(-1, 2)
        ranked = self._rank_many(xys, [sorted(a.sensor_id for a in kept[i]) for i in later], tick)
        for i, ranking in zip(later, ranked, strict=True):
            rankings[i] = ranking
        learnt: list[tuple[TrackRecord, dict[str, int], float]] = []
        for tr, got, ranking in zip(self.tracks, kept, rankings, strict=True):
            if got and ranking is not None:
                by_sid = {a.sensor_id: a.blob for a in got}
                self._report(tr, ranking, by_sid, tick, out)
                learnt.append((tr, by_sid, min(tick.weights[a.sensor_id][0] for a in got)))
        self._heights([(tr, got) for tr, got in zip(self.tracks, kept, strict=True) if got], tick.stack)
        self._learn(learnt, tick.stack)
        return kept

    def _weights(self, v: ViewBlobs, dt_s: float) -> tuple[float, float]:
        """(position, existence) weight of a view's evidence at this tick.

        A tick between two frames sees an interpolation of frames already used: it carries ``dt / period`` of a
        frame's information. Existence moves at most one view's worth per ``evidence_time_s``.
        """
        period = v.period_s if v.period_s > 0 else dt_s
        if dt_s <= 0:  # the first tick: one frame's worth
            dt_s = period if period > 0 else self.model.evidence_time_s
        w_pos = min(1.0, dt_s / period) if period > 0 else 1.0
        w_exist = min(w_pos, dt_s / self.model.evidence_time_s, 1.0)
        return max(w_pos, 1e-3), w_exist

    def _existence(self, scored: dict[str, ViewScores], hits: dict[str, dict[int, int]], tick: _Tick) -> None:
        """Raise the existence of the tracks each view detects (``hits``: per view, track -> blob), lower that of
        those it should see but misses; view after view in order of sensor ids, each capped at ``p_max``."""
        if not self.tracks:
            return
        cap = logit(self.model.p_max)
        views = list(scored.values())
        p_detect = np.array([sc.p_detect for sc in views])
        # (view, track) ln of the likelihood ratio of detected against missed, of each view's evidence.
        delta = np.array([sc.ln_miss for sc in views])
        hit = [(v, i, j) for v, sid in enumerate(scored) for i, j in hits[sid].items()]
        if hit:
            rows, cols = np.array([h[0] for h in hit]), np.array([h[1] for h in hit])
            ln_lr = np.array([views[h[0]].ln_lr[h[1], h[2]] for h in hit])
            delta[rows, cols] = np.log(1.0 - p_detect[rows, cols] + np.exp(np.minimum(ln_lr, 50.0)))
        logodds = np.array([tr.logodds for tr in self.tracks])
        for row, sid in enumerate(scored):
            moved = np.minimum(logodds + tick.weights[sid][1] * delta[row], cap)
            logodds = np.where(p_detect[row] > 0, moved, logodds)
        for tr, lo in zip(self.tracks, logodds.tolist(), strict=True):
            tr.logodds = lo

    def _update(
        self, tr: TrackRecord, got: list[_Assigned], tick: _Tick, out: TrackerOutcome, weight: FloatArray | None = None
    ) -> tuple[list[_Assigned], _Ranking | None]:
        """Update a track with the blobs assigned to it; returns those it keeps (a blob that the others show to be
        someone else's, in ``model`` mode, goes back to the unexplained ones), whose looks the caller learns, and
        in ``paper`` mode the ranking of their cameras' pairs (``model`` mode: the caller ranks every track's at
        once, :meth:`_rank_many`).

        ``weight``: the weight of each assigned blob when :meth:`_fuse` has already updated the track with them.
        """
        paper = bool(got) and weight is None and self.model.mode == "paper"
        ranking = self._rank(tr.x[:2], [a.sensor_id for a in got], tick) if paper else None
        fix: Measurement | None = None
        if ranking is not None and ranking.best is not None:
            fix = self._pair_fix(ranking.best, {a.sensor_id: a.blob for a in got}, tick)
        method: Method = "predicted"
        if fix is not None:
            tr.x, tr.p = _position_update(tr.x, tr.p, fix)
            method = fix.method
        elif got:
            if weight is None:
                (weight,) = self._fuse_tracks([tr], [got], tick)
            got = [a for a, w in zip(got, weight.tolist(), strict=True) if w >= OUTLIER_RELEASE]
            method = "least_squares"
        tr.detected = bool(got)
        if not got:
            tr.misses += 1
            tr.method, tr.sensors = "predicted", ()
            return [], None
        tr.hits += 1
        tr.misses = 0
        out.detected += 1
        tr.method = method
        if fix is None:
            ranking = self._rank(tr.x[:2], sorted(a.sensor_id for a in got), tick) if paper else None
        return got, ranking

    def _fuse(
        self, xs: FloatArray, ps: FloatArray, gots: list[list[_Assigned]], tick: _Tick, *, lines: bool = True
    ) -> tuple[FloatArray, FloatArray, list[FloatArray]]:
        """States ``xs`` (k, 4) and covariances ``ps`` (k, 4, 4) updated with every view assigned to each
        (``gots``), all at once (:func:`~resource_manager.track.fuse.fuse`), with (``lines``) the size-ratio lines
        among each one's first ``2 * MAX_PAIR_CAMERAS`` views. Also returns each one's weight of each of its
        assigned blobs (low: an outlier)."""
        m = self.model
        xs, ps, resp = fuse(
            xs,
            ps,
            Slots.of(gots, tick.stack),
            tick.stack,
            position_weight=tick.position_weight,
            outlier=(m.outlier_prob, m.outlier_scale),
            width_rel_sigma=self.birth_params.width_rel_sigma,
            line_views=2 * MAX_PAIR_CAMERAS if lines else 0,
        )
        return xs, ps, [resp[k, : len(got)] for k, got in enumerate(gots)]

    def _fuse_tracks(self, trs: list[TrackRecord], gots: list[list[_Assigned]], tick: _Tick) -> list[FloatArray]:
        """:meth:`_fuse` tracks ``trs`` in place; returns each one's weight of each of its assigned blobs."""
        if not trs:
            return []
        xs, ps, weights = self._fuse(np.array([tr.x for tr in trs]), np.array([tr.p for tr in trs]), gots, tick)
        for tr, x, p in zip(trs, xs, ps, strict=True):
            tr.x, tr.p = x.copy(), p.copy()
        return weights

    def _spread(self, v: ViewBlobs) -> Spread:
        """The spread of a view's points around a person: what its sensor states, else the model's default."""
        sigma = v.point_sigma_m if v.point_sigma_m > 0 else self.model.body_sigma_m
        return Spread(sigma * sigma, sigma * sigma)

    def _rank(self, xy: FloatArray, sids: list[str], tick: _Tick) -> _Ranking:
        """The best pair of cameras ``sids`` by the error model (or at random: ``pair_choice = random``)."""
        return self._rank_many(xy[None, :], [sids], tick)[0]

    def _rank_many(self, xys: FloatArray, sids: list[list[str]], tick: _Tick) -> list[_Ranking]:
        """:meth:`_rank` of many tracks at once (``xys`` (k, 2), each with its cameras ``sids``)."""
        st = tick.stack
        width = max((len(ids) for ids in sids), default=0)
        view = np.zeros((len(sids), width), dtype=np.int64)
        for i, ids in enumerate(sids):
            view[i, : len(ids)] = [st.rows[s] for s in ids]
        pose_sigma = np.array([tick.pose_sigma.get(v.sensor_id, 0.0) for v in st.views])
        random = self.pair_choice == "random"
        a, b, err, count = rank_pairs_many(
            xys,
            st.origin[view],
            st.sigma_rad[view],
            pose_sigma[view],
            count=np.array([len(ids) for ids in sids], dtype=np.int64),
            max_cameras=width if random else MAX_PAIR_CAMERAS,
        )
        out: list[_Ranking] = []
        for i, (ids, n) in enumerate(zip(sids, count.tolist(), strict=True)):
            if n == 0:
                out.append(_Ranking(None, 0))
                continue
            # pair_choice = random: the pairs shuffled, the first taken.
            q = int(self._rng.permutation(n)[0]) if random else 0
            out.append(_Ranking(PairCandidate(ids[a[i, q]], ids[b[i, q]], float(err[i, q])), n))
        return out

    def _pair_fix(self, pair: PairCandidate, by_sid: dict[str, int], tick: _Tick) -> Measurement | None:
        """The paper's localisation: Eq. (1) or, near colinearity, Eq. (2) with one pair of views."""
        return localize_best_pair(
            tick.views[pair.a],
            by_sid[pair.a],
            tick.views[pair.b],
            by_sid[pair.b],
            sigma_xy_a=tick.pose_sigma.get(pair.a, 0.0),
            sigma_xy_b=tick.pose_sigma.get(pair.b, 0.0),
            width_rel_sigma=self.birth_params.width_rel_sigma,
        )

    def _report(
        self, tr: TrackRecord, ranking: _Ranking, by_sid: dict[str, int], tick: _Tick, out: TrackerOutcome
    ) -> None:
        """Which pair the error model ranks best for the track, with its predicted error (the ``pairs`` key)."""
        best = ranking.best
        if best is None:
            tr.sensors = tuple(by_sid)
            tr.predicted_error_m = tr.position_sigma_m
            return
        tr.sensors = (best.a, best.b)
        fix = self._pair_fix(best, by_sid, tick)
        # The error of the method the crossover rule picks for this pair: Eq. 1's, or Eq. 2's near colinearity.
        err = fix.predicted_error_m if fix is not None else best.error_m
        tr.predicted_error_m = err if math.isfinite(err) else tr.position_sigma_m
        if tr.track_id and fix is not None:
            out.pair_entries.append(
                PairEntry(
                    track_id=tr.track_id,
                    sensor_a=best.a,
                    sensor_b=best.b,
                    predicted_error_m=float(min(max(tr.predicted_error_m, 0.0), 1e5)),
                    method=fix.method,
                    candidates=ranking.candidates,
                )
            )

    def _heights(self, seen: list[tuple[TrackRecord, list[_Assigned]]], stack: ViewStack) -> None:
        """Fuse into each track the head-top heights its views imply at its updated distance (all tracks at
        once: :func:`~resource_manager.track.fuse.fuse_heights`)."""
        if not seen:
            return
        height, height_var = fuse_heights(
            np.array([tr.x[:2] for tr, _ in seen]),
            np.array([tr.height_m for tr, _ in seen]),
            np.array([tr.height_var for tr, _ in seen]),
            Slots.of([got for _, got in seen], stack),
            stack,
        )
        for (tr, _), h, hv in zip(seen, height.tolist(), height_var.tolist(), strict=True):
            tr.height_m, tr.height_var = h, hv

    def _learn(self, learnt: list[tuple[TrackRecord, dict[str, int], float]], stack: ViewStack) -> None:
        """Links to the nodes' 2D tracks and the per-view colour looks of the blobs assigned to each of ``learnt``
        (track, sensor id -> blob, the evidence weight of those views), all tracks' looks at once."""
        offsets = stack.offsets.tolist()
        with_hist = (stack.hist_bins > 0).tolist()
        entries = [(tr, sid, stack.rows[sid], j) for tr, by_sid, _ in learnt for sid, j in by_sid.items()]
        local_id = stack.local_id[[offsets[row] + j for _, _, row, j in entries]].tolist()
        for (tr, sid, _, _), lid in zip(entries, local_id, strict=True):
            tr.links[sid] = lid
        looks: list[tuple[TrackRecord, dict[str, int], float]] = []
        for tr, by_sid, weight in learnt:
            dt = weight * self.model.evidence_time_s
            looks.append((tr, by_sid, 1.0 - math.exp(-dt / self.model.look_time_s)))
            for sid in by_sid:
                if with_hist[stack.rows[sid]]:
                    tr.look_s[sid] = tr.look_s.get(sid, 0.0) + dt
        learn_looks(looks, stack)

    # -- births and deaths ----------------------------------------------------------------------------
    def _births(self, tick: _Tick, free: dict[str, list[int]], t_ns: int) -> int:
        m = self.model
        w = min((we for _, we in tick.weights.values()), default=1.0)
        if w <= 0:
            return 0
        prior = logit(m.p_birth)
        # Started only where the evidence, tempered like every update, lifts it above the deletion threshold.
        need = (logit(m.p_delete) - prior) / w
        hyps = find_births(
            tick.views,
            free,
            self.tracks,
            m,
            self.birth_params,
            spread=lambda sid: self._spread(tick.views[sid]),
            tick=self._tick,
            min_evidence=need,
            stack=tick.stack,
        )
        if hyps:
            self._spawn(hyps, tick, t_ns, [prior + w * h.evidence for h in hyps])
        return len(hyps)

    def _spawn(self, hyps: list[Hypothesis], tick: _Tick, t_ns: int, logodds: list[float]) -> None:
        """Start a track on each hypothesis (existence ``logodds``), in order: at its best pair's fix (``paper``
        mode) or updated from a wide prior there with all its views (all at once)."""
        m, weights = self.model, tick.weights
        gots = [[_Assigned(s, j) for s, j in sorted(h.blobs.items())] for h in hyps]
        prior = np.diag([PRIOR_SIGMA**2, PRIOR_SIGMA**2, m.speed_sigma_mps**2, m.speed_sigma_mps**2])
        xs = np.array([[h.fix.xy[0], h.fix.xy[1], 0.0, 0.0] for h in hyps])
        ps = np.repeat(prior[None, :, :], len(hyps), axis=0)
        bests = [r.best for r in self._rank_many(xs[:, :2], [sorted(h.blobs) for h in hyps], tick)]
        fixes = [
            self._pair_fix(best, h.blobs, tick) if m.mode == "paper" and best is not None else None
            for h, best in zip(hyps, bests, strict=True)
        ]
        fused = [k for k, fix in enumerate(fixes) if fix is None]
        if fused:
            xs[fused], ps[fused], _ = self._fuse(xs[fused], ps[fused], [gots[k] for k in fused], tick, lines=False)
        born: list[TrackRecord] = []
        for k, (fix, best) in enumerate(zip(fixes, bests, strict=True)):
            self._serial += 1
            x, p = xs[k].copy(), ps[k].copy()
            if fix is not None:
                p[:2, :2] = fix.cov
                x[:2] = fix.xy
            tr = TrackRecord(
                serial=self._serial,
                x=x,
                p=p,
                t_ns=t_ns,
                born_ns=t_ns,
                logodds=min(logodds[k], logit(m.p_max)),
                height_m=m.height_prior_m,
                height_var=m.height_sigma_m**2,
                detected=True,
                hits=1,
                method=fix.method if fix is not None else "least_squares",
            )
            if best is not None:
                tr.sensors = (best.a, best.b)
                tr.predicted_error_m = best.error_m
            born.append(tr)
        self._heights(list(zip(born, gots, strict=True)), tick.stack)
        self._learn(
            [(tr, h.blobs, min(weights[s][0] for s in h.blobs)) for tr, h in zip(born, hyps, strict=True)], tick.stack
        )
        self.tracks.extend(born)

    def _prune(self) -> list[str]:
        """Confirm tracks whose existence reached ``p_confirm``; end those below ``p_delete``, lost, or on the same
        person as a surer track."""
        m = self.model
        confirm, delete = logit(m.p_confirm), logit(m.p_delete)
        keep: list[TrackRecord] = []
        ended: list[str] = []
        # Surest first: a confirmed track before a tentative one, then the longest seen.
        for tr in sorted(self.tracks, key=lambda t: (not t.confirmed, -t.hits, t.serial)):
            if (
                tr.logodds < delete
                or tr.position_sigma_m > m.lost_sigma_m
                or _implausible_height(tr, m)
                or any(_same_person(tr, o) for o in keep)
            ):
                if tr.track_id:
                    ended.append(tr.track_id)
                continue
            if not tr.confirmed and tr.logodds >= confirm:
                tr.confirmed = True
                tr.track_id = self.new_id()
            keep.append(tr)
        self.tracks = sorted(keep, key=lambda t: t.serial)
        return ended


HEIGHT_SIGMAS = 4.0
"""A track whose head height is surely this many of the population's sigmas from its mean is no person (a false
blob's ray crossing someone's, a robot's body): 1.1-2.3 m with the default 1.7 +- 0.15 m."""


def _implausible_height(tr: TrackRecord, model: TrackModel) -> bool:
    """Whether the track's measured head height rules out a person (the height prior, Eq. 7's r_hc in absolute)."""
    spread = math.sqrt(model.height_sigma_m**2 + tr.height_var)
    return abs(tr.height_m - model.height_prior_m) > HEIGHT_SIGMAS * spread


SAME_PERSON_CHI2 = 9.21
"""Two tracks whose positions differ by less than this (Mahalanobis², 2 dof: 99 %) and by less than a person's width
are one person followed twice (a detector's double box, two views' calibrations that disagree)."""


def _same_person(a: TrackRecord, b: TrackRecord) -> bool:
    """Whether two tracks stand where only one person fits and their estimates agree that they are one."""
    dx, dy = float(a.x[0] - b.x[0]), float(a.x[1] - b.x[1])
    if math.hypot(dx, dy) >= 2.0 * PERSON_RADIUS_M:
        return False
    s = a.p[:2, :2] + b.p[:2, :2]
    det = float(s[0, 0] * s[1, 1] - s[0, 1] * s[1, 0])
    if det <= 0:
        return True
    d2 = (float(s[1, 1]) * dx * dx - 2.0 * float(s[0, 1]) * dx * dy + float(s[0, 0]) * dy * dy) / det
    return d2 < SAME_PERSON_CHI2


OUTLIER_RELEASE = 0.5
"""An assigned blob that the track's other views make more likely an outlier than not is released."""
PRIOR_SIGMA = 1.0
"""Position spread (m) of the prior a new person's first multi-view fix starts from, around the pair's point."""


def _assign(scores: ViewScores) -> list[tuple[int, int]]:
    """One-to-one (track, blob) pairs of positive gain that maximise the total gain (Hungarian)."""
    gain = scores.gain
    if gain.size == 0:
        return []
    ok = np.isfinite(gain) & (gain > 0)
    rows = np.flatnonzero(ok.any(axis=1))
    if not rows.size:
        return []
    cols = np.flatnonzero(ok.any(axis=0))
    sub = np.where(ok, gain, 0.0)[rows][:, cols]
    r, c = linear_sum_assignment(sub, maximize=True)
    tracks, blobs = rows.tolist(), cols.tolist()
    return [(tracks[i], blobs[j]) for i, j in zip(r.tolist(), c.tolist(), strict=True) if sub[i, j] > 0]


def _position_update(x: FloatArray, p: FloatArray, fix: Measurement) -> tuple[FloatArray, FloatArray]:
    """Linear Kalman update with a floor position (the paper mode's pair fix)."""
    h = np.zeros((2, 4))
    h[0, 0] = h[1, 1] = 1.0
    s = h @ p @ h.T + fix.cov
    k = np.linalg.solve(s, h @ p).T
    x_new = x + k @ (fix.xy - x[:2])
    p_new = (np.eye(4) - k @ h) @ p
    return x_new, 0.5 * (p_new + p_new.T)
