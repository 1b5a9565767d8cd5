"""Track life: where a person can leave, who a new detection is, which two tracks are one person, who came back.

What the strong multi-view trackers do to keep one id per person, as pure functions of the tracks' state:

* **Survival from the site** (:func:`existence_caps`, :func:`left_area`): a person can leave only through an
  exit of the site's area (by default anywhere on its boundary), or out of every camera's view. Where they can,
  a track's existence is held below ``p_max``, so it ends within a few missed views; inside the area, away from
  exits, below ``p_max_inside``, so someone hidden in a crowd keeps their track. A track whose person is
  outside the area has left: it ends.
* **Returns** (:func:`match_returns`): a new person's detections next to a track no view detected this tick are
  that track found again (it lagged, or its views were hidden), not a new person.
* **One person, two tracks** (:class:`Separation`): two tracks closer than two people can stand are one person
  followed twice only if the views, since the two came close, make one person likelier than two (two people give
  the views that see both two blobs, one person one) for ``evidence_time_s`` (both published: for ``apart_time_s``
  once the views have shown them as two people); the one reported now keeps its id (else the older).
* **Re-identification** (:class:`Graveyard`): a confirmed track that ended inside the area, not through an exit
  (lost, or taken for another's person followed twice: two people no view shows apart are one track until they
  part), is remembered for ``reid_window_s``; a newly confirmed track that appeared where that person could have
  walked since (``max_speed_mps``) and whose height and colour looks agree takes the old id (one assignment over
  all such pairs).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Collection
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import linear_sum_assignment

from common.angles import wrap_angle
from common.area import Floor
from common.arrays import BoolArray, FloatArray, IntArray
from resource_manager.track.model import PERSON_RADIUS_M, Scene, TrackModel, logit
from resource_manager.track.motion import MotionModel

__all__ = [
    "CLOSE_M",
    "Graveyard",
    "Lost",
    "Separation",
    "blobs_show_two",
    "close_pairs",
    "entry_velocity",
    "existence_caps",
    "exit_reach_m",
    "left_area",
    "match_returns",
    "two_people_ln_odds",
]

CLOSE_M = 2.0 * PERSON_RADIUS_M
"""Two tracks closer than this stand where only one person fits, unless some view shows two people."""
RETURN_CHI2 = 9.21
"""A track found again lies where it was predicted: within this Mahalanobis² (2 dof: 99 %) of the new fix."""
ColourLn = Callable[[dict[str, FloatArray], dict[str, float], dict[str, FloatArray], dict[str, float]], float | None]
"""ln p(looks | one person) / p(looks | two people) of two tracks' per-view looks and their seconds of evidence
(None: no view where both were learnt, colour cannot tell)."""
REID_GATE = 3.0
"""A lost person comes back within this many sigmas of where their motion puts them."""
REID_MIN_LN_ODDS = 0.0
"""A new track takes a lost one's id when the evidence (motion, height, colour) makes them one person more likely
than two."""


def exit_reach_m(sigma_m: FloatArray, model: TrackModel) -> FloatArray:
    """How close to an exit a track must be for its person to have possibly left through it within one piece of
    evidence: two sigmas of its position plus a walk at ``speed_sigma_mps`` over ``evidence_time_s``."""
    return np.asarray(2.0 * sigma_m + model.speed_sigma_mps * model.evidence_time_s, dtype=np.float64)


Coverage = Callable[[FloatArray], BoolArray]
"""Floor points (n, 2) -> (n,) whether some camera sees a person standing there (the cameras' joint view now)."""
EDGE_DIRECTIONS = 8
"""Directions in which a track's reach is probed for the edge of the cameras' joint view."""

PAIR_OF_TRACKS = 2
"""Close tracks come in pairs: with fewer tracks there is nothing to compare."""


def at_exit(xy: FloatArray, sigma_m: FloatArray, model: TrackModel, scene: Scene, coverage: Coverage) -> BoolArray:
    """(n,) tracks standing where their person may leave: within reach (:func:`exit_reach_m`) of an exit of the
    area (by default its whole boundary), outside it, or within reach of the edge of the cameras' joint view (a
    place no camera sees lies that close); anywhere when the site declares no area."""
    n = len(xy)
    if scene.area is None:
        return np.ones(n, dtype=bool)
    if n == 0:
        return np.zeros(0, dtype=bool)
    reach = exit_reach_m(sigma_m, model)
    near = (scene.area.exit_distance(xy) <= reach) | ~scene.area.contains(xy)
    angles = np.arange(EDGE_DIRECTIONS) * (2.0 * math.pi / EDGE_DIRECTIONS)
    ring = xy[:, None, :] + reach[:, None, None] * np.stack([np.cos(angles), np.sin(angles)], axis=1)[None]
    inside = scene.area.contains(ring.reshape(-1, 2)).reshape(n, EDGE_DIRECTIONS)
    unseen = ~coverage(ring.reshape(-1, 2)).reshape(n, EDGE_DIRECTIONS)
    return np.asarray(near | (inside & unseen).any(axis=1) | ~coverage(xy), dtype=bool)


def entry_velocity(
    xy: FloatArray, sigma_m: FloatArray, model: TrackModel, scene: Scene
) -> tuple[FloatArray, FloatArray]:
    """(n, 2) mean and (n, 2, 2) covariance of the velocity of people first seen at ``xy`` (position sigma
    ``sigma_m``), whom nobody saw there before.

    Away from exits nothing says which way a new person walks: zero mean, ``speed_sigma_mps`` on each axis.
    Within reach of an exit (:func:`exit_reach_m`) they came in through it since the last look: their velocity
    across it points inward, and the faster one walks, the likelier one is to have crossed in a given time, so that
    component is the walking speed's normal law cut to its inward half and weighted by the speed (a Rayleigh law:
    mean σ_v √(π/2), variance σ_v² (2 - π/2)); the component along the exit is unchanged. Of two people coming in
    one behind the other, a stride apart, the first one's track is then predicted on into the area rather than on
    the spot where the second one appears.
    """
    n = len(xy)
    sv = model.speed_sigma_mps
    mean = np.zeros((n, 2))
    cov = np.repeat((sv * sv * np.eye(2))[None], n, axis=0)
    if scene.area is None or n == 0:
        return mean, cov
    inward = _away_from_exits(xy, scene.area)
    entering = (np.hypot(*inward.T) > 0.0) & (scene.area.exit_distance(xy) <= exit_reach_m(sigma_m, model))
    u = inward[entering]
    mean[entering] = sv * math.sqrt(math.pi / 2.0) * u
    cov[entering] -= (sv * sv * (math.pi / 2.0 - 1.0)) * np.einsum("ni,nj->nij", u, u)
    return mean, cov


ENTRY_PROBE_M = 0.05
"""Step of the finite differences that find which way is away from the nearest exit."""
CLEAR_SLOPE = 0.5
"""A distance's slope is 1 where one exit is nearest; where it is less than this, no way is clearly away."""
ON_EXIT_DIRECTIONS = 16
"""Directions probed for the way in from a point on an exit."""


def _away_from_exits(xy: FloatArray, area: Floor) -> FloatArray:
    """(n, 2) unit directions in which the distance to the nearest exit grows: the way into the area from the exit
    a person stands by (beyond the area's boundary, the way back to it; on an exit, the way that stays inside).
    Zero where no way clearly is (no exits; two exits as near)."""
    h = ENTRY_PROBE_M
    steps = np.array([[h, 0.0], [-h, 0.0], [0.0, h], [0.0, -h]])
    d = area.exit_distance((xy[:, None, :] + steps[None]).reshape(-1, 2)).reshape(len(xy), 4)
    d[~np.isfinite(d).all(axis=1)] = 0.0  # no exit anywhere: no way in
    grad = np.stack([d[:, 0] - d[:, 1], d[:, 2] - d[:, 3]], axis=1) / (2.0 * h)
    norm = np.hypot(*grad.T)
    ok = norm > CLEAR_SLOPE
    out = np.zeros_like(grad)
    out[ok] = grad[ok] / norm[ok, None]
    # Beyond the boundary (a first fix a little outside), the way in is toward the exit, not away from it.
    out[~area.contains(xy)] *= -1.0
    # On an exit (a first fix held to the area's edge) the distance grows both ways: the way in is the probe
    # direction that stays inside and gets farthest from every exit.
    on = np.flatnonzero(~ok & (area.exit_distance(xy) < h))
    if len(on):
        turns = np.linspace(0.0, 2.0 * math.pi, ON_EXIT_DIRECTIONS, endpoint=False)
        dirs = np.stack([np.cos(turns), np.sin(turns)], axis=1)
        probes = (xy[on, None, :] + h * dirs[None]).reshape(-1, 2)
        gain = np.where(area.contains(probes), area.exit_distance(probes), -np.inf).reshape(len(on), -1)
        best = np.argmax(gain, axis=1)
        clear = gain[np.arange(len(on)), best] > CLEAR_SLOPE * h
        out[on[clear]] = dirs[best[clear]]
    return out


def existence_caps(exits: BoolArray, model: TrackModel, scene: Scene) -> FloatArray:
    """(n,) the log-odds each track's existence is held below: ``p_max`` where the person may leave (``exits``:
    :func:`at_exit`; everywhere when the site declares no area), ``p_max_inside`` elsewhere inside the area."""
    inside = max(logit(model.p_max_inside), logit(model.p_max))
    if scene.area is None:
        return np.full(len(exits), logit(model.p_max))
    return np.where(exits, logit(model.p_max), inside)


def left_area(xy: FloatArray, sigma_m: FloatArray, scene: Scene) -> BoolArray:
    """(n,) tracks whose person is surely outside the site's area (beyond two sigmas and a person's width of it)."""
    if scene.area is None or not len(xy):
        return np.zeros(len(xy), dtype=bool)
    outside = ~scene.area.contains(xy)
    far = scene.area.boundary_distance(xy) > 2.0 * sigma_m + PERSON_RADIUS_M
    return np.asarray(outside & far, dtype=bool)


def match_returns(
    hyp_xy: FloatArray, hyp_cov: FloatArray, track_xy: FloatArray, track_cov: FloatArray
) -> list[tuple[int, int]]:
    """(hypothesis, track) pairs: new people's fixes ``hyp_xy`` (h, 2) with covariances ``hyp_cov`` (h, 2, 2) that
    are coasting tracks at ``track_xy`` (t, 2), ``track_cov`` (t, 2, 2) found again; one assignment over all pairs
    within ``RETURN_CHI2``, by likelihood."""
    if not len(hyp_xy) or not len(track_xy):
        return []
    s = hyp_cov[:, None] + track_cov[None, :]
    d = hyp_xy[:, None, :] - track_xy[None, :, :]
    det = s[..., 0, 0] * s[..., 1, 1] - s[..., 0, 1] * s[..., 1, 0]
    d2 = (
        s[..., 1, 1] * d[..., 0] ** 2 - 2.0 * s[..., 0, 1] * d[..., 0] * d[..., 1] + s[..., 0, 0] * d[..., 1] ** 2
    ) / det
    ok = d2 <= RETURN_CHI2
    if not ok.any():
        return []
    cost = np.where(ok, d2 + np.log(det), 1e12)
    r, c = linear_sum_assignment(cost)
    return [(a, b) for a, b in zip(r.tolist(), c.tolist(), strict=True) if ok[a, b]]


def close_pairs(xy: FloatArray) -> tuple[IntArray, FloatArray]:
    """(k, 2) rows (a < b) of the tracks at ``xy`` (n, 2) within two people's width (``2 CLOSE_M``) of each other,
    and the (n, n) distances between all of them. Pairs are followed a little beyond where they merge (``CLOSE_M``),
    so that the clock of a pair that hovers about that distance does not restart."""
    d = np.hypot(xy[:, None, 0] - xy[None, :, 0], xy[:, None, 1] - xy[None, :, 1])
    return np.argwhere(np.triu(d < 2.0 * CLOSE_M, 1)).astype(np.int64), d


SECOND_BLOB_PROB = 0.05
"""Chance that a view shows one person as two blobs, one on each side of two tracks that follow them (a detector's
double box, a false blob beside them): how little one view's two blobs prove two people."""
PAIR_SURE_LN_ODDS = math.log(99.0)
"""The views' word on two close tracks is held within 99 % either way, so that what they show now decides within a
fraction of a second, however long the two walked together before (one of them may have lost its person since)."""
SLIVER_SHARE = 0.5
"""Two people side by side, at about the same distance from a view, show about as wide: a blob narrower than this
share of the one beside it is as likely a piece of that one (a node that cut one person's blob in two) as someone
else."""


def blobs_show_two(
    track_bearing: tuple[FloatArray, FloatArray], blob_bearing: tuple[FloatArray, FloatArray],
    blob_width: tuple[FloatArray, FloatArray],
) -> BoolArray:  # fmt: skip
    """Whether a view's two blobs, one given to each of two close tracks (bearings ``track_bearing`` from the view,
    rad), show two people: each lies on its own track's side (nearer its bearing than the other's), and neither is
    a sliver beside the other (:data:`SLIVER_SHARE`). Element by element over arrays of such pairs."""
    (ta, tb), (ba, bb), (wa, wb) = track_bearing, blob_bearing, blob_width
    own_a = np.abs(wrap_angle(ba - ta)) <= np.abs(wrap_angle(ba - tb))
    own_b = np.abs(wrap_angle(bb - tb)) <= np.abs(wrap_angle(bb - ta))
    return np.asarray(own_a & own_b & (np.minimum(wa, wb) >= SLIVER_SHARE * np.maximum(wa, wb)), dtype=bool)


def two_people_ln_odds(p_a: FloatArray, p_b: FloatArray, got_a: BoolArray, got_b: BoolArray) -> FloatArray:
    """ln p(views | two people) / p(views | one person followed twice) of two close tracks, per view: ``p_a``,
    ``p_b`` each track's chance of detection by the view, ``got_a``, ``got_b`` whether the view gave each a blob
    of its own (both: two distinct blobs).

    Two people give the view two blobs with chance p_a p_b, one with p_a (1 - p_b) + p_b (1 - p_a), none with
    (1 - p_a)(1 - p_b); one person, detected with the likelier chance p, gives one blob (p), none (1 - p), or two
    only by a second blob beside them (:data:`SECOND_BLOB_PROB`). A view that cannot see either says nothing."""
    p_a, p_b = np.clip(p_a, 0.0, 1.0 - 1e-6), np.clip(p_b, 0.0, 1.0 - 1e-6)
    p_one = np.maximum(p_a, p_b)
    tiny = 1e-12
    both = np.log(np.maximum(np.minimum(p_a, p_b), tiny) / SECOND_BLOB_PROB)
    single = np.log(np.maximum(p_a * (1.0 - p_b) + p_b * (1.0 - p_a), tiny) / np.maximum(p_one, tiny))
    neither = np.log(np.maximum((1.0 - p_a) * (1.0 - p_b), tiny) / np.maximum(1.0 - p_one, tiny))
    out = np.where(got_a & got_b, both, np.where(got_a | got_b, single, neither))
    # A blob given to a track the view could not see (a return) is no evidence of how many people stand there.
    known = (p_one > 0.0) & ((p_a > 0.0) | ~got_a) & ((p_b > 0.0) | ~got_b)
    return np.where(known, out, 0.0)


@dataclass
class Separation:
    """For tracks that stand close together, whether the views show them as two people or as one followed twice.

    Each pair within two people's width (``2 CLOSE_M``) of each other gathers, from the instant it came that close,
    the log-odds of two people against one (:func:`two_people_ln_odds` of every view that should see them, held
    within :data:`PAIR_SURE_LN_ODDS`; two blobs count only where they show two people, :func:`blobs_show_two`): two
    people side by side give the views that see both two blobs, tick after tick, however little their bearings
    differ; one person followed twice gives each view one blob, now to one track, now to the other, and two only
    where a detector boxes them twice. A pair is seen apart at an instant its log-odds are for two people.
    """

    last: dict[tuple[int, int], int] = field(default_factory=dict)
    """(serial, serial), the smaller first -> the last instant the two were seen apart."""
    since: dict[tuple[int, int], int] = field(default_factory=dict)
    """(serial, serial) -> the instant they came close together (and have stayed since)."""
    ln_odds: dict[tuple[int, int], float] = field(default_factory=dict)
    """(serial, serial) -> log-odds of two people against one, gathered since they came within ``2 CLOSE_M``."""

    def note(self, serials: list[int], xy: FloatArray, evidence: dict[tuple[int, int], float], t_ns: int) -> None:
        """Add, for every close pair of tracks, this tick's ``evidence`` (track rows (a, b), a < b -> ln odds of two
        people against one; absent: none), and remember the pairs it leaves more likely two people as seen apart at
        ``t_ns``; pairs no longer close are forgotten."""
        keep: dict[tuple[int, int], int] = {}
        together: dict[tuple[int, int], int] = {}
        odds: dict[tuple[int, int], float] = {}
        if len(xy) >= PAIR_OF_TRACKS:
            pairs, d = close_pairs(xy)
            for a, b in pairs.tolist():
                key = (min(serials[a], serials[b]), max(serials[a], serials[b]))
                gathered = self.ln_odds.get(key, 0.0) + evidence.get((a, b), 0.0)
                odds[key] = min(max(gathered, -PAIR_SURE_LN_ODDS), PAIR_SURE_LN_ODDS)
                if odds[key] > 0.0:
                    keep[key] = t_ns
                elif key in self.last:
                    keep[key] = self.last[key]
                if d[a, b] < CLOSE_M:
                    together[key] = self.since.get(key, t_ns)
        self.last = keep
        self.since = together
        self.ln_odds = odds

    def told_apart(self, serials: Collection[int], t_ns: int) -> None:
        """Every two of ``serials`` that stand close are known to be two people at ``t_ns`` (another manager
        that follows them publishes them as two)."""
        for key in self.since.keys() | self.last.keys():
            if key[0] in serials and key[1] in serials:
                self.last[key] = max(t_ns, self.last.get(key, t_ns))

    def together_s(self, a: int, b: int, t_ns: int) -> float:
        """Seconds serials ``a`` and ``b`` have stood within ``CLOSE_M`` of each other (0 if they do not)."""
        key = (min(a, b), max(a, b))
        return (t_ns - self.since[key]) / 1e9 if key in self.since else 0.0

    def since_apart_s(self, a: int, b: int, t_ns: int) -> float:
        """Seconds since serials ``a`` and ``b`` were last seen apart (infinite if never)."""
        key = (min(a, b), max(a, b))
        return (t_ns - self.last[key]) / 1e9 if key in self.last else math.inf


@dataclass(frozen=True, slots=True)
class Lost:
    """A confirmed track that ended inside the area: what re-identification compares new tracks with."""

    track_id: str
    ended_ns: int
    seen_ns: int
    """When it was last detected, and where: ``x`` (4,), ``p`` (4, 4) at that instant."""
    x: FloatArray
    p: FloatArray
    height_m: float
    height_var: float
    looks: dict[str, FloatArray]
    look_s: dict[str, float]
    serial: int


@dataclass
class Graveyard:
    """Confirmed tracks that ended inside the area, kept ``reid_window_s`` for their people to come back."""

    lost: list[Lost] = field(default_factory=list)

    def remember(self, lost: Lost) -> None:
        self.lost.append(lost)

    def forget_before(self, t_ns: int) -> None:
        self.lost = [g for g in self.lost if g.ended_ns >= t_ns]

    def take(self, ids: set[str]) -> None:
        self.lost = [g for g in self.lost if g.track_id not in ids]

    def match(
        self,
        new: list[NewTrack],
        others_xy: FloatArray,
        *,
        model: TrackModel,
        motion: MotionModel,
        colour_ln: ColourLn,
        area_m2: float | None,
    ) -> list[tuple[int, Lost]]:
        """(index into ``new``, the lost track it is) for each newly confirmed track that is a lost one back: one
        assignment over all pairs the speed bound allows and whose first place the lost one's motion puts within
        ``REID_GATE`` sigmas, each scored by the log likelihood ratio of "one person" over "two people" of where
        (against a new person anywhere in the area, ``area_m2``, or anywhere the speed bound reaches), how tall and
        how they look, and taken when above ``REID_MIN_LN_ODDS``.

        Where the two cannot be compared by colour (a node that sends none, or views neither was seen in), motion
        and height alone decide only when no one else (``others_xy``: the tracks already there) is as likely to be
        the lost person. Within the motion model's ``turn_time_s`` of the last sighting, where the lost person
        should be is still known: the new track must stand nearer to it than anyone tracked does (someone nearer is
        where the lost track's person went, or whom it was following twice). Later, in a crowd, where someone lost
        was last seen says little about who the new one is: nobody tracked may stand where they could be.
        """
        if not new or not self.lost:
            return []
        score = np.full((len(new), len(self.lost)), -np.inf)
        for i, nt in enumerate(new):
            for j, g in enumerate(self.lost):
                gap_s = (nt.born_ns - g.seen_ns) / 1e9
                if gap_s <= 0:
                    continue  # seen while the lost one still was: another person
                reach = model.max_speed_mps * gap_s + 2.0 * PERSON_RADIUS_M
                if float(np.hypot(*(nt.first_xy - g.x[:2]))) > reach:
                    continue
                mean, cov = _predicted(g, gap_s, motion)
                d2 = _mahalanobis2(nt.first_xy, mean, cov)
                if d2 > REID_GATE**2:
                    continue
                colour = colour_ln(nt.looks, nt.look_s, g.looks, g.look_s)
                if colour is None:
                    rival = float(d2) if gap_s <= model.turn_time_s else REID_GATE**2
                    if bool((_mahalanobis2(others_xy, mean, cov) <= rival).any()):
                        continue
                ln_same = -0.5 * (d2 + math.log(float(np.linalg.det(cov)))) - math.log(2.0 * math.pi)
                ln_other = -math.log(area_m2 if area_m2 else math.pi * reach * reach)
                score[i, j] = ln_same - ln_other + _height_ln(nt, g, model) + (colour or 0.0)
        ok = score > REID_MIN_LN_ODDS
        if not ok.any():
            return []
        r, c = linear_sum_assignment(np.where(ok, -score, 1e12))
        return [(i, self.lost[j]) for i, j in zip(r.tolist(), c.tolist(), strict=True) if ok[i, j]]


@dataclass(frozen=True, slots=True)
class NewTrack:
    """A newly confirmed track, as re-identification sees it."""

    born_ns: int
    first_xy: FloatArray
    height_m: float
    height_var: float
    looks: dict[str, FloatArray]
    look_s: dict[str, float]


def _predicted(g: Lost, gap_s: float, motion: MotionModel) -> tuple[FloatArray, FloatArray]:
    """Where the lost person is, ``gap_s`` after they were last seen: mean (2,) and covariance (2, 2) of their
    motion from there, a body's width wider."""
    f, q = motion.transition(gap_s)
    return (f @ g.x)[:2], (f @ g.p @ f.T + q)[:2, :2] + (PERSON_RADIUS_M**2) * np.eye(2)


def _mahalanobis2(xy: FloatArray, mean: FloatArray, cov: FloatArray) -> FloatArray:
    """Squared Mahalanobis distances of points ``xy`` (..., 2) from ``mean`` (2,) under ``cov`` (2, 2)."""
    d = np.asarray(xy, dtype=np.float64) - mean
    return np.asarray(np.einsum("...i,ij,...j->...", d, np.linalg.inv(cov), d), dtype=np.float64)


def _height_ln(nt: NewTrack, g: Lost, model: TrackModel) -> float:
    """ln N(new height; lost height) / N(new height; people's heights): the same person is as tall."""
    var_same = nt.height_var + g.height_var + 2.0 * (0.5 * model.height_sigma_m) ** 2
    var_other = nt.height_var + model.height_sigma_m**2
    same = -0.5 * ((nt.height_m - g.height_m) ** 2 / var_same + math.log(var_same))
    other = -0.5 * ((nt.height_m - model.height_prior_m) ** 2 / var_other + math.log(var_other))
    return same - other


def rows_of(mask: BoolArray) -> IntArray:
    return np.flatnonzero(mask).astype(np.int64)
