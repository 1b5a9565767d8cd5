"""Each tick's measurement update: every track with the views assigned to it, and the camera pair that reports it.

Given the blobs each view assigned to each track (:mod:`.tracker`), :class:`Updater` updates the tracks'
filter rows (:mod:`.filter`) with every view assigned to each, each with its own covariance (``model`` mode), or
with the pair of them the error model ranks best, by Eq. (1) or Eq. (2) (``paper`` mode); a blob the other
views show to be someone else's goes back to the unexplained ones. It reports each detected track's best pair
(the ``pairs`` key, with its predicted error) and learns its head height, colour looks and the nodes' 2D track
ids. All tracks at once wherever the arithmetic allows; only the pair report is a loop.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np

from common.arrays import FloatArray, IntArray
from common.schema import MAX_METRES, Method, PairEntry
from resource_manager.stereo.localize import Measurement, localize_best_pair
from resource_manager.stereo.pairs import PairCandidate, rank_pairs_many
from resource_manager.track.filter import TrackFilter
from resource_manager.track.fuse import Slots
from resource_manager.track.looks import learn_looks
from resource_manager.track.model import TrackModel
from resource_manager.track.observe import Visibility, feet_cut_prob
from resource_manager.track.state import TrackRecord
from resource_manager.views.blobs import Views

__all__ = ["MAX_PAIR_CAMERAS", "Assigned", "Tick", "Updater"]

MAX_PAIR_CAMERAS = 5
"""Only the cameras nearest a person are paired when ranking pairs by the error model (5 cameras: 10 pairs)."""
OUTLIER_RELEASE = 0.5
"""An assigned blob that the track's other views make more likely an outlier than not is released."""


class Assigned(NamedTuple):
    """One view's blob assigned to a track."""

    sensor_id: str
    blob: int


@dataclass(frozen=True, slots=True)
class Tick:
    """What every stage of one tick reads: the views, their evidence weights, the cameras' position errors."""

    views: Views
    """Every view's blobs, in order of sensor ids."""
    weights: dict[str, tuple[float, float]]
    """sensor id -> (position, existence) weight of its evidence at this tick."""
    pose_sigma: dict[str, float]
    position_weight: FloatArray
    """(s,) the position weight of each view."""
    visibility: Visibility | None = None
    """What each view should see of each track, row for row with the filter (its feet hidden, and how far a cut
    box can read); None: nothing hidden."""


class Ranking(NamedTuple):
    """The pair of a track's cameras chosen among how many."""

    best: PairCandidate | None
    candidates: int


@dataclass
class Updated:
    """What one tick's update did."""

    kept: list[list[Assigned]]
    """Per track, the blobs it kept (an outlier goes back to the unexplained ones)."""
    pair_entries: list[PairEntry] = field(default_factory=list)


class Updater:
    """The measurement update of one tracker (see the module docstring).

    Args:
        model: the tracker's model.
        width_rel_sigma: the relative width error of the size-ratio method (Eq. 2).
        pair_choice: ``error_model`` (the paper), or ``random``: a baseline the error model is measured against.
    """

    def __init__(self, model: TrackModel, width_rel_sigma: float, pair_choice: str, seed: int = 0) -> None:
        self.model = model
        self.width_rel_sigma = width_rel_sigma
        self.pair_choice = pair_choice
        self._rng = np.random.default_rng(seed)

    def update(
        self, filt: TrackFilter, tracks: list[TrackRecord], assigned: list[list[Assigned]], tick: Tick, t_ns: int
    ) -> Updated:
        """Update every track (row for row with ``filt``) with the blobs assigned to it; returns those each kept
        and the pair report of each detected, confirmed track."""
        out = Updated(kept=[[] for _ in tracks])
        rankings: list[Ranking | None] = [None] * len(tracks)
        methods: list[Method] = ["least_squares"] * len(tracks)
        if self.model.mode == "model":
            rows = [i for i, got in enumerate(assigned) if got]
            weights = self.fuse(filt, np.array(rows, dtype=np.int64), [assigned[i] for i in rows], tick)
            for i, w in zip(rows, weights, strict=True):
                out.kept[i] = [a for a, wi in zip(assigned[i], w.tolist(), strict=True) if wi >= OUTLIER_RELEASE]
        else:
            for i, got in enumerate(assigned):
                out.kept[i], rankings[i], methods[i] = self._paper_update(filt, i, got, tick)
        later = [i for i, got in enumerate(out.kept) if got and rankings[i] is None]
        ranked = self.rank_many(filt.x[later, :2], [sorted(a.sensor_id for a in out.kept[i]) for i in later], tick)
        for i, ranked_i in zip(later, ranked, strict=True):
            rankings[i] = ranked_i
        sigma_m = filt.position_sigma().tolist()
        learnt: list[tuple[TrackRecord, dict[str, int], float]] = []
        for i, (tr, got) in enumerate(zip(tracks, out.kept, strict=True)):
            tr.detected = bool(got)
            if not got:
                tr.misses += 1
                tr.method, tr.sensors = "predicted", ()
                continue
            tr.hits += 1
            tr.misses = 0
            tr.seen_ns = t_ns
            tr.method = methods[i]
            ranking = rankings[i]
            by_sid = {a.sensor_id: a.blob for a in got}
            if ranking is not None:
                self.report(tr, sigma_m[i], ranking, by_sid=by_sid, tick=tick, entries=out.pair_entries)
            learnt.append((tr, by_sid, min(tick.weights[a.sensor_id][0] for a in got)))
        seen = [i for i, got in enumerate(out.kept) if got]
        filt.fuse_heights(np.array(seen, dtype=np.int64), [out.kept[i] for i in seen], tick.views)
        self.learn(learnt, tick.views)
        return out

    def fuse(
        self, filt: TrackFilter, rows: IntArray, gots: list[list[Assigned]], tick: Tick, *, lines: bool = True
    ) -> list[FloatArray]:
        """Update filter ``rows`` with every view assigned to each (``gots``), all at once, with (``lines``) the
        size-ratio lines among each one's first ``2 * MAX_PAIR_CAMERAS`` views; returns each one's weight of each
        of its blobs (low: an outlier)."""
        return filt.fuse(
            rows,
            [[(a.sensor_id, a.blob) for a in got] for got in gots],
            tick.views,
            **self._fuse_args(rows, tick, lines=lines),
        )

    def _fuse_args(self, rows: IntArray, tick: Tick, *, lines: bool) -> dict[str, Any]:
        """The arguments of :meth:`TrackFilter.fuse` for filter ``rows`` at this tick."""
        m = self.model
        # Rows the tick's visibility did not cover (tracks started this tick) count as unhidden.
        hidden = np.zeros((tick.views.n_views, len(rows)))
        reach = np.zeros_like(hidden)
        near = np.zeros_like(hidden)
        if tick.visibility is not None:
            known = rows < tick.visibility.feet_hidden.shape[1]
            hidden[:, known] = tick.visibility.feet_hidden[:, rows[known]]
            reach[:, known] = tick.visibility.cut_reach_m[:, rows[known]]
            near[:, known] = tick.visibility.cover_near_m[:, rows[known]]
        return {
            "feet_cut": feet_cut_prob(hidden, m),
            "cut_reach_m": reach,
            "cover_near_m": near,
            "position_weight": tick.position_weight,
            "outlier": (m.outlier_prob, m.outlier_scale),
            "width_rel_sigma": self.width_rel_sigma,
            "line_views": 2 * MAX_PAIR_CAMERAS if lines else 0,
        }

    def leave_one_out(
        self, filt: TrackFilter, assigned: list[list[Assigned]], tick: Tick
    ) -> tuple[FloatArray, FloatArray]:
        """Where each view should look for each track (row for row with ``filt``), given what the other views
        assigned to it: (s, n, 2) positions and (s, n, 2, 2) covariances, from the track's prediction updated with
        the blobs ``assigned`` to it by every view but that one (its update with them all, that view's information
        taken out again: :func:`.motion.update_without_each`). Nothing is kept."""
        views = tick.views
        xy = np.repeat(filt.x[None, :, :2], views.n_views, axis=0)
        cov = np.repeat(filt.p[None, :, :2, :2], views.n_views, axis=0)
        r = np.array([i for i, got in enumerate(assigned) if got], dtype=np.int64)
        if not len(r):
            return xy, cov
        slots = Slots.of([[(a.sensor_id, a.blob) for a in assigned[i]] for i in r.tolist()], views)
        # Where to look needs the bearings and feet only: Eq. 2's size-ratio lines are left out (they cost a third).
        x, p, x_out, p_out = filt.fused_without_each(r, slots, views, **self._fuse_args(r, tick, lines=False))
        xy[:, r], cov[:, r] = x[None, :, :2], p[None, :, :2, :2]
        # Each view that gave a track a blob looks for it without that blob (where it was a track's only blob: where
        # the track was predicted).
        track, slot, view = slots.track, slots.slot, slots.view
        xy[view, r[track]], cov[view, r[track]] = x_out[track, slot, :2], p_out[track, slot, :2, :2]
        return xy, cov

    def _paper_update(
        self, filt: TrackFilter, row: int, got: list[Assigned], tick: Tick
    ) -> tuple[list[Assigned], Ranking | None, Method]:
        """``paper`` mode: the best pair of the assigned views localises the track (Eq. 1 or Eq. 2); without a
        pair fix, every view updates it as in ``model`` mode. Returns the blobs kept, their pairs' ranking and
        the method that placed the track."""
        if not got:
            return [], None, "predicted"
        ranking = self.rank_many(filt.x[[row], :2], [[a.sensor_id for a in got]], tick)[0]
        fix = None if ranking.best is None else self.pair_fix(ranking.best, {a.sensor_id: a.blob for a in got}, tick)
        if fix is not None:
            filt.fix(row, fix.xy, fix.cov)
            return got, ranking, fix.method
        (weight,) = self.fuse(filt, np.array([row], dtype=np.int64), [got], tick)
        kept = [a for a, w in zip(got, weight.tolist(), strict=True) if w >= OUTLIER_RELEASE]
        if not kept:
            return [], None, "predicted"
        return kept, self.rank_many(filt.x[[row], :2], [sorted(a.sensor_id for a in kept)], tick)[0], "least_squares"

    def rank_many(self, xys: FloatArray, sids: list[list[str]], tick: Tick) -> list[Ranking]:
        """The best pair of each track's cameras ``sids`` (at ``xys`` (k, 2)) by the error model (or at random:
        ``pair_choice = random``), all at once."""
        st = tick.views
        width = max((len(ids) for ids in sids), default=0)
        view = np.zeros((len(sids), width), dtype=np.int64)
        for i, ids in enumerate(sids):
            view[i, : len(ids)] = [st.rows[s] for s in ids]
        pose_sigma = np.array([tick.pose_sigma.get(sid, 0.0) for sid in st.sensor_ids])
        random = self.pair_choice == "random"
        a, b, err, count = rank_pairs_many(
            np.asarray(xys, dtype=np.float64).reshape(-1, 2),
            st.origin[view],
            st.sigma_rad[view],
            pose_sigma[view],
            count=np.array([len(ids) for ids in sids], dtype=np.int64),
            max_cameras=width if random else MAX_PAIR_CAMERAS,
        )
        out: list[Ranking] = []
        for i, (ids, n) in enumerate(zip(sids, count.tolist(), strict=True)):
            if n == 0:
                out.append(Ranking(None, 0))
                continue
            # pair_choice = random: the pairs shuffled, the first taken.
            q = int(self._rng.permutation(n)[0]) if random else 0
            out.append(Ranking(PairCandidate(ids[a[i, q]], ids[b[i, q]], float(err[i, q])), n))
        return out

    def pair_fix(self, pair: PairCandidate, by_sid: dict[str, int], tick: Tick) -> Measurement | None:
        """The paper's localisation: Eq. (1) or, near colinearity, Eq. (2) with one pair of views."""
        return localize_best_pair(
            tick.views,
            tick.views.entry(pair.a, by_sid[pair.a]),
            tick.views.entry(pair.b, by_sid[pair.b]),
            sigma_xy_a=tick.pose_sigma.get(pair.a, 0.0),
            sigma_xy_b=tick.pose_sigma.get(pair.b, 0.0),
            width_rel_sigma=self.width_rel_sigma,
        )

    def report(
        self,
        tr: TrackRecord,
        sigma_m: float,
        ranking: Ranking,
        *,
        by_sid: dict[str, int],
        tick: Tick,
        entries: list[PairEntry],
    ) -> None:
        """Which pair the error model ranks best for the track, with its predicted error (the ``pairs`` key)."""
        best = ranking.best
        if best is None:
            tr.sensors = tuple(by_sid)
            tr.predicted_error_m = sigma_m
            return
        tr.sensors = (best.a, best.b)
        fix = self.pair_fix(best, by_sid, tick)
        # The error of the method the crossover rule picks for this pair: Eq. 1's, or Eq. 2's near colinearity.
        err = fix.predicted_error_m if fix is not None else best.error_m
        tr.predicted_error_m = err if math.isfinite(err) else sigma_m
        if tr.track_id and fix is not None:
            entries.append(
                PairEntry(
                    track_id=tr.track_id,
                    sensor_a=best.a,
                    sensor_b=best.b,
                    predicted_error_m=float(min(max(tr.predicted_error_m, 0.0), MAX_METRES)),
                    method=fix.method,
                    candidates=ranking.candidates,
                )
            )

    def learn(self, learnt: list[tuple[TrackRecord, dict[str, int], float]], views: Views) -> None:
        """Links to the nodes' 2D tracks and the per-view colour looks of the blobs assigned to each of ``learnt``
        (track, sensor id -> blob, the evidence weight of those views), all tracks' looks at once."""
        offsets = views.offsets.tolist()
        with_hist = (views.hist_bins > 0).tolist()
        entries = [(tr, sid, views.rows[sid], j) for tr, by_sid, _ in learnt for sid, j in by_sid.items()]
        local_id = views.local_id[[offsets[row] + j for _, _, row, j in entries]].tolist()
        for (tr, sid, _, _), lid in zip(entries, local_id, strict=True):
            tr.links[sid] = lid
        looks: list[tuple[TrackRecord, dict[str, int], float]] = []
        for tr, by_sid, weight in learnt:
            dt = weight * self.model.evidence_time_s
            looks.append((tr, by_sid, 1.0 - math.exp(-dt / self.model.look_time_s)))
            for sid in by_sid:
                if with_hist[views.rows[sid]]:
                    tr.look_s[sid] = tr.look_s.get(sid, 0.0) + dt
        learn_looks(looks, views)
