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
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from common.arrays import BoolArray, FloatArray, IntArray
from resource_manager.stereo.localize import Measurement, localize_best_pair
from resource_manager.stereo.match import Matcher, MatchParams, match_matrices
from resource_manager.track.model import PERSON_RADIUS_M, Scene, TrackModel
from resource_manager.track.observe import Spread, TrackTable, ViewStack, Visibility, score_views, visibility_many
from resource_manager.track.state import TrackRecord
from resource_manager.views.blobs import ViewBlobs
from resource_manager.views.build import subset_view

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
    """sensor id -> index (in the full view) of the blob each supporting view gives."""
    evidence: float
    """Log likelihood ratio of "a person" over "false detections", all views."""


def _hypotheses(
    sub: dict[str, ViewBlobs], free: dict[str, list[int]], params: BirthParams, tick: int
) -> list[tuple[Measurement, str, int, str, int]]:
    """(fix, view a, blob, view b, blob) of every Eq. 7 match of unexplained blobs (``sub``: each view with only
    its unexplained blobs ``free``), blob indices in full views."""
    sids = sorted(sub)
    pairs = list(itertools.combinations(sids, 2))
    if len(pairs) > params.max_pairs:
        start = (tick * params.max_pairs) % len(pairs)
        pairs = (pairs[start:] + pairs[:start])[: params.max_pairs]
    if not pairs:
        return []
    mats = match_matrices([(sub[a], sub[b]) for a, b in pairs], params.match)
    out = []
    for (a, b), mm in zip(pairs, mats, strict=True):
        for i, j in params.matcher.match(mm.r, params.threshold):
            fix = localize_best_pair(sub[a], i, sub[b], j, width_rel_sigma=params.width_rel_sigma)
            if fix is not None:
                out.append((fix, a, free[a][i], b, free[b][j]))
    return out


def _singles(
    sub: dict[str, ViewBlobs], free: dict[str, list[int]], max_sigma_m: float
) -> list[tuple[Measurement, str, int, str, int]]:
    """(fix, view, blob, "", -1) of every unexplained blob a camera's feet range alone places to within
    ``max_sigma_m`` along its ray (its bearing places it across)."""
    out = []
    for sid, v in sub.items():
        if v.mono_range_m is None or v.mono_sigma_m is None:
            continue
        for i in np.flatnonzero(np.isfinite(v.mono_range_m) & (v.mono_sigma_m <= max_sigma_m)).tolist():
            r, sr = float(v.mono_range_m[i]), float(v.mono_sigma_m[i])
            u = np.array([math.cos(float(v.bearing_rad[i])), math.sin(float(v.bearing_rad[i]))])
            across = np.array([-u[1], u[0]])
            cov = sr**2 * np.outer(u, u) + (r * v.sigma_rad) ** 2 * np.outer(across, across)
            fix = Measurement(
                xy=v.origin_xy + r * u,
                cov=cov,
                height_m=0.0,
                method="least_squares",
                sensors=(sid,),
                predicted_error_m=sr,
                blobs=((sid, free[sid][i]),),
            )
            out.append((fix, sid, free[sid][i], "", -1))
    return out


def _provisional(
    found: list[tuple[Measurement, str, int, str, int]], views: dict[str, ViewBlobs], model: TrackModel
) -> tuple[TrackTable, list[TrackRecord]]:
    """Hypotheses as tracks to score the views against: their places (the pair's points scatter too: the prior
    spread is the fix's and a body's) and heights, and as their looks the colours of their defining blobs (the
    other views' blobs are compared with them: Eq. 7's r_is across views)."""
    xy = np.array([fix.xy for fix, *_ in found], dtype=np.float64).reshape(-1, 2)
    cov = np.array([fix.cov + model.body_sigma_m**2 * np.eye(2) for fix, *_ in found]).reshape(-1, 2, 2)
    height = np.array([fix.height_m if fix.height_m > 0 else model.height_prior_m for fix, *_ in found])
    table = TrackTable(xy, cov, height, np.full(len(found), model.height_sigma_m**2))
    records = []
    for _, a, ia, b, ib in found:
        tr = TrackRecord(serial=0, born_ns=0)
        for sid, j in ((a, ia), (b, ib)):
            hs = views[sid].hist_sqrt if sid else None
            if hs is not None:
                tr.looks[sid] = hs[j].copy()
                tr.look_s[sid] = model.look_min_s
        records.append(tr)
    return table, records


def _in_area(xy: FloatArray, scene: Scene) -> bool:
    """Whether a person at ``xy`` stands inside the site's area (anywhere, where it declares none)."""
    return scene.area is None or bool(scene.area.contains(xy[None, :])[0])


def _sure(v: ViewBlobs, blobs: list[int], birth_confidence: float) -> list[int]:
    """The blobs among ``blobs`` of ``v`` sure enough to start a person."""
    if v.confidence is None:
        return list(blobs)
    return [j for j in blobs if float(v.confidence[j]) >= birth_confidence]


def _near(xy: FloatArray, track_xy: FloatArray) -> bool:
    """Whether a person at ``xy`` would stand within two person radii of one at a row of ``track_xy``."""
    return bool(track_xy.size) and float(np.min(np.hypot(*(track_xy - xy).T))) < 2.0 * PERSON_RADIUS_M


def find_births(
    views: dict[str, ViewBlobs],
    free: dict[str, list[int]],
    blockers: TrackTable,
    model: TrackModel,
    *,
    scene: Scene,
    params: BirthParams,
    spread: Callable[[str], Spread],
    tick: int,
    min_evidence: float,
    stack: ViewStack | None = None,
) -> list[Hypothesis]:
    """The new people among the unexplained blobs ``free`` (sensor id -> blob indices), best first.

    ``blockers``: the tracks the views detected: nobody is started within two person radii of one, and they hide
    the hypotheses from the cameras behind them. Only blobs sure enough (``birth_confidence``) define a
    hypothesis; any unexplained blob may support one. ``min_evidence``: the log likelihood ratio a hypothesis
    needs (the prior and the deletion threshold). ``stack``: ``views`` stacked in order of sensor ids with their
    ``spread`` (default: stacked here).
    """
    sure = {sid: _sure(views[sid], blobs, model.birth_confidence) for sid, blobs in free.items()}
    sure_sub = {sid: subset_view(views[sid], blobs) for sid, blobs in sure.items() if blobs}
    found = _hypotheses(sure_sub, sure, params, tick) + _singles(sure_sub, sure, model.publish_sigma_m)
    # Nobody is started outside the area, nor within two person radii of a track: those go before they are scored.
    found = [h for h in found if _in_area(h[0].xy, scene) and not _near(h[0].xy, blockers.xy)]
    if not found:
        return []
    sids = sorted(views)
    every = stack if stack is not None else ViewStack.of([views[sid] for sid in sids], [spread(sid) for sid in sids])
    gains = _Gains.of(found, views, free, every, blockers, model=model, max_range_m=scene.max_range_m)
    return _pick(found, gains, blockers, min_evidence)


@dataclass(slots=True)
class _Gains:
    """What each hypothesis gains from each unexplained blob (the blobs side by side, view after view)."""

    gain: FloatArray
    """(hypothesis, blob) log likelihood ratio of the blob being that person."""
    misses: FloatArray
    """(hypothesis,) the views' miss terms (hidden by the tracks only)."""
    offsets: IntArray
    """Where each view's blobs start in ``gain``'s columns, and the end."""
    column: dict[tuple[str, int], int]
    """(sensor id, blob index) -> column."""
    blob_of: list[int]
    """Column -> blob index in its view."""
    free_sids: list[str]
    """The views with unexplained blobs, in column order."""
    alive: BoolArray
    """Which hypotheses may be started at all (one view: only where no other camera has a clear view)."""

    @classmethod
    def of(
        cls,
        found: list[tuple[Measurement, str, int, str, int]],
        views: dict[str, ViewBlobs],
        free: dict[str, list[int]],
        every: ViewStack,
        blockers: TrackTable,
        *,
        model: TrackModel,
        max_range_m: float,
    ) -> _Gains:
        sids = sorted(views)
        with_free = [i for i, sid in enumerate(sids) if free.get(sid)]
        cand_table, cands = _provisional(found, views, model)
        # Per view: each hypothesis' gain for each unexplained blob, and its miss term (hidden by the tracks only).
        vis = visibility_many(every, cand_table, model, max_range_m, blockers=blockers)
        pd = vis.p_detect
        misses = np.zeros(len(cands))
        for row in np.log1p(-np.minimum(pd, 1.0 - 1e-9)):
            misses += row
        unexplained = every.subset(with_free, [free[sids[i]] for i in with_free])
        scores = score_views(
            unexplained,
            cands,
            cand_table,
            Visibility(pd[with_free], vis.feet_hidden[with_free], vis.cut_reach_m[with_free]),
            model=model,
            max_range_m=max_range_m,
        )
        alive = np.ones(len(cands), dtype=bool)
        row = {sid: i for i, sid in enumerate(sids)}
        for k, (_, a, _, b, _) in enumerate(found):
            if not b:  # one view: only where no other camera has a clear view of the spot
                others = np.delete(pd[:, k], row[a])
                alive[k] = not bool(np.any(others > model.p_detect_hidden + 1e-9))
        return cls(
            gain=np.concatenate([sc.gain for sc in scores], axis=1),
            misses=misses,
            offsets=unexplained.offsets,
            column={(sids[i], j): c for c, (i, j) in enumerate((i, j) for i in with_free for j in free[sids[i]])},
            blob_of=[j for i in with_free for j in free[sids[i]]],
            free_sids=[sids[i] for i in with_free],
            alive=alive,
        )


def _pick(
    found: list[tuple[Measurement, str, int, str, int]], g: _Gains, blockers: TrackTable, min_evidence: float
) -> list[Hypothesis]:
    """Greedily, best evidence first: start a hypothesis, take its blobs from the others."""
    gain, alive, column = g.gain, g.alive, g.column
    starts = g.offsets[:-1]
    open_ = np.ones(gain.shape[1], dtype=bool)
    out: list[Hypothesis] = []
    taken_xy = blockers.xy.reshape(-1, 2)
    while alive.any():
        # Each hypothesis' evidence: every view's best blob not yet taken, where it fits (gain > 0).
        open_gain = np.where(open_, gain, -np.inf)
        best = np.maximum.reduceat(open_gain, starts, axis=1)
        evidence = g.misses.copy()
        for v in range(best.shape[1]):
            evidence += np.maximum(best[:, v], 0.0)
        evidence = np.where(alive, evidence, -np.inf)
        c = int(np.argmax(evidence))
        if evidence[c] < min_evidence:
            break
        fix, a, ia, b, ib = found[c]
        blobs: dict[str, int] = {}
        for v, (lo, hi) in enumerate(zip(starts.tolist(), g.offsets[1:].tolist(), strict=True)):
            if best[c, v] > 0:
                blobs[g.free_sids[v]] = g.blob_of[lo + int(np.argmax(open_gain[c, lo:hi]))]
        alive[c] = False
        if blobs.get(a) != ia or (b and blobs.get(b) != ib):
            continue  # its own pair no longer fits it best: another hypothesis of those blobs will say
        if _near(fix.xy, taken_xy):
            continue  # beside a person started before it in this tick
        out.append(Hypothesis(fix, blobs, float(evidence[c])))
        taken_xy = np.vstack([taken_xy, fix.xy[None, :]])
        for sid, j in blobs.items():
            open_[column[sid, j]] = False
        for k2, (_, a2, i2, b2, j2) in enumerate(found):
            if alive[k2] and (not open_[column[a2, i2]] or (b2 and not open_[column[b2, j2]])):
                alive[k2] = False
    return out
