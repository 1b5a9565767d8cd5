"""New people: blobs that no track explains, paired across views by Eq. (7) and judged by every view.

1. The unexplained blobs of every two views are scored by the paper's 3D blob match (Eq. 7: colour, ray
   convergence, width and height consistency, feet on the floor) and paired by the configured matcher; each
   pair's rays give a hypothesised person (Eq. 1, or Eq. 2 near colinearity). Where no second camera has a
   clear view (out of every other picture, or hidden there by people nearer to it), stereo cannot start anyone:
   there a blob whose feet a calibrated camera places on the floor to within ``publish_sigma_m`` is a
   hypothesis of its own, which starts tentative and is confirmed over time. Only blobs the nodes are sure of
   (``birth_confidence``) define hypotheses, and only inside the site's area.
2. Each hypothesis is put to every view as a provisional track (:mod:`.observe`): a view whose unexplained
   blob fits it supports it, a view that should see it and has nothing there counts against it. The sum is
   the log likelihood ratio of "a new person" against "false detections that happen to agree".
3. Hypotheses are taken best first; each takes its supporting blobs, so the other hypotheses built on those
   blobs (the same person from other pairs, or ghosts of crossing rays) lose them. A hypothesis is started
   only if the prior ``p_birth`` times that evidence leaves it above ``p_delete``, and nobody stands within two
   person radii of a track a view detected (next to a track nobody detected, it may be that track found
   again: :mod:`.life`).
4. Its first position comes, in ``paper`` mode, from the pair of its supporting views the error model ranks best
   (Eq. 1 or Eq. 2); in ``model`` mode from all its views at once. The error model's best pair is reported.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from common.arrays import BoolArray, FloatArray, IntArray
from resource_manager.stereo.localize import Measurement, localize_best_pair
from resource_manager.stereo.match import Matcher, MatchParams, match_matrices
from resource_manager.track.model import PERSON_RADIUS_M, Scene, TrackModel
from resource_manager.track.observe import Looks, TrackTable, score_views, visibility_many
from resource_manager.track.recall import detector_misses
from resource_manager.track.state import TrackRecord
from resource_manager.views.blobs import Subset, Views

__all__ = ["BirthParams", "Hypothesis", "find_births"]


@dataclass(frozen=True, slots=True)
class BirthParams:
    match: MatchParams
    """Eq. 7's measures."""
    threshold: float
    """tau: a pair of blobs is matched only above this confidence."""
    matcher: Matcher
    max_pairs: int
    """Most camera pairs matched per tick (round robin over ticks beyond that)."""
    width_rel_sigma: float


@dataclass(frozen=True, slots=True)
class Hypothesis:
    """A new person the views agree on."""

    fix: Measurement
    """Where the defining pair puts them (Eq. 1 or Eq. 2)."""
    blobs: dict[str, int]
    """sensor id -> index (in its view) of the blob each supporting view gives."""
    evidence: float
    """Log likelihood ratio of "a person" over "false detections", all views."""


class _Found(NamedTuple):
    """A hypothesis before it is judged: its fix and the blobs (entries of the views) that define it."""

    fix: Measurement
    a: int
    b: int
    """-1: one view's feet alone place it."""


def _hypotheses(views: Views, sure: Subset, params: BirthParams, tick: int) -> list[_Found]:
    """Every Eq. 7 match of the blobs ``sure`` across two views."""
    pairs = list(itertools.combinations(range(len(sure.rows)), 2))
    if len(pairs) > params.max_pairs:
        start = (tick * params.max_pairs) % len(pairs)
        pairs = (pairs[start:] + pairs[:start])[: params.max_pairs]
    if not pairs:
        return []
    mats = match_matrices(views, pairs, params.match, blobs=sure)
    out = []
    for (a, b), mm in zip(pairs, mats, strict=True):
        blobs_a, blobs_b = sure.part(a).tolist(), sure.part(b).tolist()
        for i, j in params.matcher.match(mm.r, params.threshold):
            fix = localize_best_pair(views, blobs_a[i], blobs_b[j], width_rel_sigma=params.width_rel_sigma)
            if fix is not None:
                out.append(_Found(fix, blobs_a[i], blobs_b[j]))
    return out


def _singles(views: Views, sure: Subset, max_sigma_m: float) -> list[_Found]:
    """Every blob of ``sure`` that a camera's feet range alone places to within ``max_sigma_m`` along its ray (its
    bearing places it across)."""
    out = []
    for k, row in enumerate(sure.rows.tolist()):
        blobs = sure.part(k)
        ranges, sigmas = views.mono_range_m[blobs], views.mono_sigma_m[blobs]
        sid, sigma_rad = views.sensor_ids[row], float(views.sigma_rad[row])
        for i in np.flatnonzero(np.isfinite(ranges) & (sigmas <= max_sigma_m)).tolist():
            r, sr = float(ranges[i]), float(sigmas[i])
            entry = int(blobs[i])
            bearing = float(views.bearing_rad[entry])
            u = np.array([math.cos(bearing), math.sin(bearing)])
            across = np.array([-u[1], u[0]])
            cov = sr**2 * np.outer(u, u) + (r * sigma_rad) ** 2 * np.outer(across, across)
            fix = Measurement(
                xy=views.origin[row] + r * u,
                cov=cov,
                height_m=0.0,
                method="least_squares",
                sensors=(sid,),
                predicted_error_m=sr,
                blobs=((sid, entry - int(views.offsets[row])),),
            )
            out.append(_Found(fix, entry, -1))
    return out


def _provisional(found: list[_Found], views: Views, model: TrackModel) -> tuple[TrackTable, list[TrackRecord]]:
    """Hypotheses as tracks to score the views against: their places (the pair's points scatter too: the prior
    spread is the fix's and a body's) and heights, and as their looks the colours of their defining blobs (the
    other views' blobs are compared with them: Eq. 7's r_is across views)."""
    xy = np.array([f.fix.xy for f in found], dtype=np.float64).reshape(-1, 2)
    cov = np.array([f.fix.cov + model.body_sigma_m**2 * np.eye(2) for f in found]).reshape(-1, 2, 2)
    height = np.array([f.fix.height_m if f.fix.height_m > 0 else model.height_prior_m for f in found])
    table = TrackTable(xy, cov, height, np.full(len(found), model.height_sigma_m**2))
    records = []
    for f in found:
        tr = TrackRecord(serial=0, born_ns=0)
        for entry in (f.a, f.b):
            hs = views.hist_of(entry) if entry >= 0 else None
            if hs is not None:
                sid = views.sensor_ids[int(views.view_of[entry])]
                tr.looks[sid] = hs.copy()
                tr.look_s[sid] = model.look_min_s
        records.append(tr)
    return table, records


def _in_area(xy: FloatArray, scene: Scene) -> bool:
    """Whether a person at ``xy`` stands inside the site's area (anywhere, where it declares none)."""
    return scene.area is None or bool(scene.area.contains(xy[None, :])[0])


def _near(xy: FloatArray, track_xy: FloatArray) -> bool:
    """Whether a person at ``xy`` would stand within two person radii of one at a row of ``track_xy``."""
    return bool(track_xy.size) and float(np.min(np.hypot(*(track_xy - xy).T))) < 2.0 * PERSON_RADIUS_M


def find_births(
    views: Views,
    unexplained: BoolArray,
    blockers: TrackTable,
    model: TrackModel,
    *,
    scene: Scene,
    params: BirthParams,
    tick: int,
    min_evidence: float,
) -> list[Hypothesis]:
    """The new people among the blobs no track explains (``unexplained``: (m,) over the blobs of ``views``), best
    first.

    ``blockers``: the tracks the views detected: nobody is started within two person radii of one, and they hide
    the hypotheses from the cameras behind them. Only blobs sure enough (``birth_confidence``) define a
    hypothesis; any unexplained blob may support one. ``min_evidence``: the log likelihood ratio a hypothesis
    needs (the prior and the deletion threshold).
    """
    sure = unexplained & (views.confidence >= model.birth_confidence)
    # A box the picture's side cuts does not say where its person's centre is: alone, it starts nobody.
    whole = views.subset(sure & (views.side_cut == 0))
    found = _hypotheses(views, views.subset(sure), params, tick) + _singles(views, whole, model.publish_sigma_m)
    # Nobody is started outside the area, nor within two person radii of a track: those go before they are scored.
    found = [f for f in found if _in_area(f.fix.xy, scene) and not _near(f.fix.xy, blockers.xy)]
    if not found:
        return []
    free = views.subset(unexplained)
    gains = _Gains.of(found, views, free, blockers, model=model, max_range_m=scene.max_range_m)
    return _pick(found, gains, views, blockers, min_evidence)


@dataclass(slots=True)
class _Gains:
    """What each hypothesis gains from each unexplained blob (the blobs side by side, view after view)."""

    gain: FloatArray
    """(hypothesis, blob) log likelihood ratio of the blob being that person."""
    misses: FloatArray
    """(hypothesis,) the views' miss terms (hidden by the tracks only), each view's on its own."""
    ln_miss: FloatArray
    """(view, hypothesis) each view's miss term."""
    free: Subset
    """The unexplained blobs: ``gain``'s columns."""
    column: IntArray
    """(m,) each blob's column (-1: not unexplained)."""
    alive: BoolArray
    """Which hypotheses may be started at all (one view: only where no other camera has a clear view)."""

    @classmethod
    def of(
        cls,
        found: list[_Found],
        views: Views,
        free: Subset,
        blockers: TrackTable,
        *,
        model: TrackModel,
        max_range_m: float,
    ) -> _Gains:
        cand_table, cands = _provisional(found, views, model)
        # Per view: each hypothesis' gain for each unexplained blob, and its miss term (hidden by the tracks only).
        vis = visibility_many(views, cand_table, model, max_range_m, blockers=blockers)
        pd = vis.p_detect
        ln_miss = np.log1p(-np.minimum(pd, 1.0 - 1e-9))
        misses = ln_miss.sum(axis=0)
        looks = Looks.of(cands, views, model.look_min_s)
        scores = score_views(views, free, cands, cand_table, vis, model=model, max_range_m=max_range_m, looks=looks)
        alive = np.ones(len(cands), dtype=bool)
        for k, f in enumerate(found):
            if f.b < 0:  # one view: only where no other camera has a clear view of the spot
                others = np.delete(pd[:, k], views.view_of[f.a])
                alive[k] = not bool(np.any(others > model.p_detect_hidden + 1e-9))
        column = np.full(views.n, -1, dtype=np.int64)
        column[free.entries] = np.arange(len(free.entries))
        return cls(
            gain=np.concatenate([sc.gain for sc in scores], axis=1),
            misses=misses,
            ln_miss=ln_miss,
            free=free,
            column=column,
            alive=alive,
        )


def _shared_misses(g: _Gains, views: Views, fits: BoolArray) -> FloatArray:
    """(hypothesis,) what turns the views' miss terms, each view's on its own (:attr:`_Gains.misses`), into one per
    multi-view detector (:attr:`Views.shared_detector`): where some of its views have a blob that fits the hypothesis
    (``fits``: (hypothesis, view of ``g.free``)), its other views' misses say nothing; where none does, they are one
    miss, of the likeliest view's probability (:func:`~.recall.detector_misses`; the tracker counts a track's miss at
    the detector's learnt recall instead)."""
    out = np.zeros(g.ln_miss.shape[1])
    if not views.shared_groups:
        return out
    # (view, hypothesis) whether each view of the tick has a blob that fits each hypothesis.
    fit_all = np.zeros(g.ln_miss.shape, dtype=bool)
    fit_all[g.free.rows] = fits.T
    for rows in views.shared_groups.values():
        fit = fit_all[rows]
        ln_miss = np.where(fit, 0.0, g.ln_miss[rows])  # a view with a fitting blob counts its gain, not its miss
        out += detector_misses(ln_miss, fit, g.ln_miss[rows].min(axis=0)).sum(axis=0) - ln_miss.sum(axis=0)
    return out


def _pick(found: list[_Found], g: _Gains, views: Views, blockers: TrackTable, min_evidence: float) -> list[Hypothesis]:
    """Greedily, best evidence first: start a hypothesis, take its blobs from the others."""
    gain, alive, column = g.gain, g.alive, g.column.tolist()
    starts = g.free.offsets[:-1]
    spans = list(zip(starts.tolist(), g.free.offsets[1:].tolist(), strict=True))
    rows, entries = g.free.rows.tolist(), g.free.entries.tolist()
    open_ = np.ones(gain.shape[1], dtype=bool)
    out: list[Hypothesis] = []
    taken_xy = blockers.xy.reshape(-1, 2)
    while alive.any():
        # Each hypothesis' evidence: every view's best blob not yet taken, where it fits (gain > 0).
        open_gain = np.where(open_, gain, -np.inf)
        best = np.maximum.reduceat(open_gain, starts, axis=1)
        evidence = g.misses + _shared_misses(g, views, best > 0)
        for v in range(best.shape[1]):
            evidence += np.maximum(best[:, v], 0.0)
        evidence = np.where(alive, evidence, -np.inf)
        c = int(np.argmax(evidence))
        if evidence[c] < min_evidence:
            break
        f = found[c]
        chosen = {
            rows[v]: entries[lo + int(np.argmax(open_gain[c, lo:hi]))]
            for v, (lo, hi) in enumerate(spans)
            if best[c, v] > 0
        }
        alive[c] = False
        if chosen.get(int(views.view_of[f.a])) != f.a or (f.b >= 0 and chosen.get(int(views.view_of[f.b])) != f.b):
            continue  # its own pair no longer fits it best: another hypothesis of those blobs will say
        if _near(f.fix.xy, taken_xy):
            continue  # beside a person started before it in this tick
        offsets = views.offsets
        blobs = {views.sensor_ids[r]: e - int(offsets[r]) for r, e in chosen.items()}
        out.append(Hypothesis(f.fix, blobs, float(evidence[c])))
        taken_xy = np.vstack([taken_xy, f.fix.xy[None, :]])
        for e in chosen.values():
            open_[column[e]] = False
        for k2, f2 in enumerate(found):
            if alive[k2] and (not open_[column[f2.a]] or (f2.b >= 0 and not open_[column[f2.b]])):
                alive[k2] = False
    return out
