"""What each camera should see of each track, and how well each of its blobs fits: one cost for assignment.

For a view and the predicted tracks this computes, for every (track, blob), the log likelihood ratio of "this
blob is that person" against "this blob is a false detection", and for every track the log likelihood of "the
view missed that person". The ratio multiplies independent terms:

* **position**: the blob's bearing and, where a perspective camera sees the feet, its floor distance, against
  the track's predicted bearing and distance; the innovation covariance is the track's position covariance
  seen from the camera plus the measurement's own (the sensor's bearing error, the pose's error, the spread of
  the point seen around the person's floor position; a box the picture's side cuts is read as part of the
  person: :func:`cut_bearing`). The density is a Gaussian with a wider outlier
  component (a badly drawn box still belongs to someone). A false detection is uniform over the camera's field
  of view and range, ``clutter_per_view`` of them per frame;
* **head height**: the head-top height the blob's top implies at the track's distance, against the track's
  height (a false detection's height is uniform over ``height_range_m``); the paper's height consistency;
* **colour**: the Bhattacharyya distance of the blob's histogram to the track's look in this view (the paper's
  intensity similarity, per view, since one shirt looks different from another side);
* **continuity**: the blob continues the node's 2D track last assigned to this track.

Whether the camera should see the person at all (in its picture, in range, not hidden behind someone nearer)
sets the detection probability P_D of both alternatives: a detected person scores ln P_D + ln(g / λ), a missed
one ln(1 - P_D).

Every view of a tick is scored at once, on the tick's :class:`~resource_manager.views.blobs.Views` (or some of its
blobs: a :class:`~resource_manager.views.blobs.Subset`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from common.angles import TWO_PI, wrap_angle
from common.arrays import BoolArray, FloatArray, IntArray
from resource_manager.track.looks import colour_ln_lr
from resource_manager.track.model import PERSON_RADIUS_M, TrackModel
from resource_manager.track.motion import MIN_RANGE_M, quadratic_form
from resource_manager.track.state import TrackRecord
from resource_manager.views.blobs import Subset, Views

__all__ = [
    "Looks",
    "TrackTable",
    "ViewScores",
    "Visibility",
    "bearing_var",
    "cut_bearing",
    "feet_cut_prob",
    "feet_ln",
    "gains_claimed",
    "in_any_view",
    "score_views",
    "seen_by",
    "visibility_many",
]

LN_2PI = math.log(TWO_PI)
HALF = 0.5
"""A distance beyond the gate is weighed only for a person whose feet are more than half hidden."""
LN_HALF = math.log(HALF)


PER_VIEW_NDIM = 3
"""A :class:`TrackTable` whose positions have this many dimensions gives each view its own (s, n, 2)."""


@dataclass(frozen=True, slots=True)
class TrackTable:
    """The predicted tracks as arrays (built once per tick, shared by every view), or where each view should
    look for them (:func:`score_views` only: one row per view)."""

    xy: FloatArray
    """(n, 2) positions, or (s, n, 2): each view's."""
    pos_cov: FloatArray
    """(n, 2, 2) position covariances, or (s, n, 2, 2): each view's."""
    height: FloatArray
    """(n,) head-top heights."""
    height_var: FloatArray

    @property
    def n(self) -> int:
        return int(self.xy.shape[-2])


@dataclass(frozen=True, slots=True)
class Looks:
    """Every track's colour looks learnt for at least ``look_min_s``, as arrays (built once per tick: the looks
    change only when the update learns), for each histogram size the views send: (n, s, bins) each track's look in
    each view and (n, s) 1/0 whether it has one there, and the (n, bins) sum and (n,) count over the views it has
    one in."""

    by_bins: dict[int, tuple[FloatArray, FloatArray, FloatArray, FloatArray]]

    @staticmethod
    def of(tracks: Sequence[TrackRecord], views: Views, min_s: float) -> Looks:
        return Looks({bins: _look_arrays(tracks, views, bins, min_s) for bins in views.hist_sqrt})

    def take(self, rows: IntArray) -> Looks:
        """The looks of tracks ``rows`` only."""
        return Looks({bins: (own[rows], ok[rows], total[rows], count[rows]) for bins, (own, ok, total, count) in
                      self.by_bins.items()})  # fmt: skip


@dataclass(frozen=True, slots=True)
class ViewScores:
    """One view against every track."""

    ln_lr: FloatArray
    """(n, m) ln [P_D g(blob | track) / λ(blob)]: -inf outside the gate or where the track is not visible."""
    ln_miss: FloatArray
    """(n,) ln(1 - P_D): the view detects nothing of the track."""
    p_detect: FloatArray
    """(n,) P_D of each track in this view (0: it cannot see the track)."""

    @property
    def gain(self) -> FloatArray:
        """(n, m) what assigning the blob to the track gains over leaving both apart (> 0: worth it)."""
        return self.ln_lr - self.ln_miss[:, None]

    def gain_claimed(self, claim: FloatArray) -> FloatArray:
        """(n, m) :attr:`gain` of tracks that are someone only with probability ``claim`` (n,): such a track explains
        a blob with r P_D g / λ, and none with 1 - r P_D (at r = 1, :attr:`gain`)."""
        return self.ln_lr + _claim_terms(claim, self.p_detect)[:, None]


def gains_claimed(scores: Sequence[ViewScores], claim: FloatArray) -> FloatArray:
    """(n, m) :meth:`ViewScores.gain_claimed` of every view of ``scores``, their blobs side by side, worked out at
    once (the same numbers as view by view)."""
    counts = [sc.ln_lr.shape[1] for sc in scores]
    terms = _claim_terms(claim, np.stack([sc.p_detect for sc in scores]))
    return np.concatenate([sc.ln_lr for sc in scores], axis=1) + np.repeat(terms, counts, axis=0).T


def _claim_terms(claim: FloatArray, p_detect: FloatArray) -> FloatArray:
    """ln r - ln(1 - r P_D) of tracks that are someone with probability ``claim`` (n,), detected with
    probabilities ``p_detect`` (n,) or (s, n): what :meth:`ViewScores.gain_claimed` adds to a track's gains."""
    sure = np.minimum(np.maximum(claim, 1e-9), 1.0)  # np.clip's rule, without its per-call cost
    return np.asarray(np.log(sure) - np.log1p(-np.minimum(sure * p_detect, 1.0 - 1e-9)), dtype=np.float64)


class _Cover(NamedTuple):
    """Silhouettes that may hide people: (s, 1 or n, k) azimuth, half width, bottom and top elevations in each
    view, and (s, n, k) whether each stands in front of each person."""

    az: FloatArray
    half: FloatArray
    lo: FloatArray
    hi: FloatArray
    front: BoolArray


class Visibility(NamedTuple):
    """What each camera should see of each track (:func:`visibility_many`)."""

    p_detect: FloatArray
    """(s, n) probability that each view detects each track (0: out of its picture or range)."""
    feet_hidden: FloatArray
    """(s, n) share of each track's feet that someone nearer or a camera's body hides in each view: a box there
    ends above the feet."""
    cut_reach_m: FloatArray
    """(s, n) the farthest floor distance a box cut by those covers can read: the box's bottom is at most the
    highest cover's top, whose line of sight meets the floor there (inf: a cover that reaches the camera's height
    or above; 0: nothing covers the feet. Neither bounds a cut)."""
    cover_near_m: FloatArray
    """(s, n) in a view whose blobs merge people who overlap in its picture (:attr:`Views.blobs_merge`), the floor
    distance of the nearest person in front who covers part of the track's feet: a merged blob's
    bottom may be its feet, nearer than the track's (0: nothing, or a view whose blobs do not merge)."""


def bearing_var(views: Views, rows: IntArray, dist: FloatArray) -> FloatArray:
    """Bearing variance of a person at ``dist`` from the camera of view ``rows`` (each element its own): the
    sensor's and its yaw's, its position's and the spread of the point seen around the person."""
    d = np.maximum(dist, MIN_RANGE_M)
    spread = views.point_var_m2[rows] + views.sigma_xy_m[rows] ** 2
    return np.asarray(views.sigma_rad[rows] ** 2 + spread / (d * d), dtype=np.float64)


def cut_bearing(
    bearing_rad: FloatArray, width_rad: FloatArray, side_cut: FloatArray, dist: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Blob bearings as bearings of a person at ``dist`` from the camera, and the variance that adds (all four
    broadcast together).

    A box the picture's side cuts (``side_cut``: :attr:`~resource_manager.views.blobs.Views.side_cut`) shows only
    part of the person, its inner edge theirs: their centre lies beyond the box's by half the part of one person's
    width (at that distance) the box lacks, give or take that much and a quarter of the width (people are not all
    one width)."""
    one = 2.0 * np.arctan(PERSON_RADIUS_M / np.maximum(dist, MIN_RANGE_M))
    cut = np.abs(side_cut)
    half_lack = 0.5 * np.maximum(one - width_rad, 0.0) * cut
    bearing = np.asarray(bearing_rad + side_cut * half_lack, dtype=np.float64)
    return bearing, np.asarray(half_lack * half_lack + cut * (0.25 * one) ** 2, dtype=np.float64)


def visibility_many(
    views: Views, table: TrackTable, model: TrackModel, max_range_m: float, blockers: TrackTable | None = None
) -> Visibility:
    """Each track in each view: its detection probability, 0 out of the picture or ``max_range_m``, lower when
    someone nearer stands on the same bearing (one of the tracks of ``blockers``; default: of ``table`` itself,
    new people's hypotheses are hidden by the tracks, not by each other) or another camera's body does; and the
    share of its feet those hide. A view whose boxes are a multi-view detector's (:attr:`Views.shared_detector`: floor
    detections drawn into its picture) has a person at ``p_detect`` whether or not nearer people cover them."""
    n = table.n
    p = np.zeros((views.n_views, n))
    if n == 0 or views.n_views == 0:
        return Visibility(p, p.copy(), p.copy(), p.copy())
    dist, seen = _in_view(views, table, max_range_m)
    hiders = None
    if n + (blockers.n if blockers is not None else 0) > 1:
        hiders = (table, dist, seen) if blockers is None else (blockers, *_in_view(views, blockers, max_range_m))
    covered, feet, reach, near = _covered(views, table, dist, hiders)
    p = np.where(seen, model.p_detect_hidden + (model.p_detect - model.p_detect_hidden) * (1.0 - covered), 0.0)
    for rows in views.shared_groups.values():
        p[rows] = np.where(seen[rows], model.p_detect, 0.0)
    return Visibility(p, np.where(seen, feet, 0.0), reach, np.where(seen & views.blobs_merge[:, None], near, 0.0))


def in_any_view(views: Views, xy: FloatArray, height_m: float, max_range_m: float) -> BoolArray:
    """(n,) whether some camera of ``views`` has a person ``height_m`` tall standing at ``xy`` (n, 2) in its picture
    and range."""
    return np.asarray(seen_by(views, xy, height_m, max_range_m).any(axis=0), dtype=bool)


def seen_by(views: Views, xy: FloatArray, height_m: float, max_range_m: float) -> BoolArray:
    """(s, n) whether each camera of ``views`` has a person ``height_m`` tall standing at ``xy`` (n, 2) in its
    picture and range."""
    xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    if not views.n_views or not len(xy):
        return np.zeros((views.n_views, len(xy)), dtype=bool)
    n = len(xy)
    table = TrackTable(xy, np.zeros((n, 2, 2)), np.full(n, height_m), np.zeros(n))
    return np.asarray(_in_view(views, table, max_range_m)[1], dtype=bool)


def _in_view(views: Views, table: TrackTable, max_range_m: float) -> tuple[FloatArray, BoolArray]:
    """(s, n) distance of each track from each camera and whether it is in the camera's picture and range."""
    d = table.xy[None, :, :] - views.origin[:, None, :]
    dist = np.hypot(d[:, :, 0], d[:, :, 1])
    seen = (dist > MIN_RANGE_M) & (dist <= max_range_m)
    feet = head = None
    for i, (image, fov) in enumerate(zip(views.image, views.fov, strict=True)):
        if image is not None:
            if feet is None or head is None:
                feet = np.column_stack([table.xy, np.zeros(table.n)])
                head = np.column_stack([table.xy, table.height])
            both = image.inside(np.concatenate([feet, head]))
            seen[i] &= both[: table.n] | both[table.n :]
        elif fov is not None:
            seen[i] &= np.abs(wrap_angle(np.arctan2(d[i, :, 1], d[i, :, 0]) - fov[0])) <= fov[1]
    return dist, seen


def _silhouettes(
    views: Views, table: TrackTable, dist: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """(s, n) azimuth, half width, feet and head elevations of each track's silhouette in each view."""
    d = table.xy[None, :, :] - views.origin[:, None, :]
    r = np.maximum(dist, MIN_RANGE_M)
    z = views.z_m[:, None]
    return np.arctan2(d[:, :, 1], d[:, :, 0]), PERSON_RADIUS_M / r, np.arctan2(-z, r), np.arctan2(table.height - z, r)


def _covered(
    views: Views,
    table: TrackTable,
    dist: FloatArray,
    hiders: tuple[TrackTable, FloatArray, BoolArray] | None,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """(s, n) share of each person's silhouette (feet to head, one person wide) that nearer people (``hiders``: a
    table, its (s, k) distances and whether each is in each picture) and the other cameras' bodies cover in each
    picture, treating the covers as independent: 1 - Π(1 - overlap_k / area); (s, n) the share of the feet they
    cover (of the person's width, where a cover reaches above the feet); and (s, n) the farthest floor distance a
    box cut by them can read (:attr:`Visibility.cut_reach_m`; 0 where nothing covers the feet); and (s, n) the floor
    distance of the nearest person among them that covers part of the feet (0: none).

    Angular rectangles: azimuth ± radius / distance, elevation from the floor to the head top (a body: to its
    camera). A camera above the crowd sees the head of someone behind a nearer person; one at head height does
    not; a high camera sees over a short robot, but not the feet just behind it.
    """
    az, half, lo, hi = (a[:, :, None] for a in _silhouettes(views, table, dist))
    area = np.maximum(2.0 * half * (hi - lo), 1e-12)
    clear = np.ones(dist.shape)
    clear_feet = np.ones(dist.shape)
    reach = np.zeros(dist.shape)
    near = np.full(dist.shape, math.inf)
    z = views.z_m[:, None, None]
    # Each cover, and the floor distance of its feet where a foreground blob may take it in (a person; None: a body).
    covers: list[tuple[_Cover, FloatArray | None]] = []
    if hiders is not None:
        others, hdist, hseen = hiders
        if others is table:
            az_k, half_k, lo_k, hi_k = (np.swapaxes(a, 1, 2) for a in (az, half, lo, hi))
        else:
            az_k, half_k, lo_k, hi_k = (a[:, None, :] for a in _silhouettes(views, others, hdist))
        # [v, i, k]: k stands in front of i (nearer by more than a person's depth) and can hide.
        front = (hdist[:, None, :] < dist[:, :, None] - 2.0 * PERSON_RADIUS_M) & hseen[:, None, :]
        covers.append((_Cover(az_k, half_k, lo_k, hi_k, front), hdist[:, None, :]))
    bodies = np.flatnonzero(views.body_radius_m > 0.0)
    if bodies.size:
        # A camera's body is no foreground: a static one is part of the background, a robot is told apart by its
        # colour bands (a sighting, not a person's blob).
        covers.append((_bodies(views, bodies, dist), None))
    for (az_k, half_k, lo_k, hi_k, front), feet_at in covers:
        width = np.maximum(np.minimum(half, half_k) * 2.0, 0.0)
        over_az = np.clip(half + half_k - np.abs(wrap_angle(az - az_k)), 0.0, width)
        over_el = np.clip(np.minimum(hi, hi_k) - np.maximum(lo, lo_k), 0.0, None)
        clear *= np.prod(1.0 - np.where(front, np.minimum(over_az * over_el / area, 1.0), 0.0), axis=2)
        feet = front & (hi_k >= lo)
        clear_feet *= np.prod(1.0 - np.where(feet, np.minimum(over_az / (2.0 * half), 1.0), 0.0), axis=2)
        # A box cut by this cover ends at its top at most: that line of sight meets the floor this far away (a
        # cover whose top is level with the camera or above can cut a box anywhere).
        top_floor = np.where(hi_k < 0.0, z / np.tan(-np.minimum(hi_k, -1e-9)), math.inf)
        on_feet = feet & (over_az > 0.0)
        reach = np.maximum(reach, np.max(np.where(on_feet, top_floor, 0.0), axis=2, initial=0.0))
        if feet_at is not None:  # ...and a blob that takes this person in ends at their feet.
            near = np.minimum(near, np.min(np.where(on_feet, feet_at, math.inf), axis=2, initial=math.inf))
    return (
        np.asarray(1.0 - clear, dtype=np.float64),
        np.asarray(1.0 - clear_feet, dtype=np.float64),
        np.asarray(reach, dtype=np.float64),
        np.asarray(np.where(np.isfinite(near), near, 0.0), dtype=np.float64),
    )


def _bodies(views: Views, bodies: IntArray, dist: FloatArray) -> _Cover:
    """The silhouettes of the cameras' bodies ``bodies`` (view rows) in every view, as (s, 1, b) azimuth, half
    width, floor and top elevations, and (s, n, b) whether each stands in front of each track (a camera's own body
    hides nothing from it)."""
    d = views.origin[bodies][None, :, :] - views.origin[:, None, :]
    r = np.hypot(d[:, :, 0], d[:, :, 1])
    radius = views.body_radius_m[bodies][None, :]
    r_safe = np.maximum(r, MIN_RANGE_M)
    z = views.z_m[:, None]
    az = np.arctan2(d[:, :, 1], d[:, :, 0])
    half = np.arcsin(np.minimum(radius / r_safe, 1.0))
    lo = np.arctan2(-z, np.maximum(r - radius, MIN_RANGE_M))
    hi = np.arctan2(views.z_m[bodies][None, :] - z, r_safe)
    own = r <= radius + PERSON_RADIUS_M  # its own body, or one it stands against
    front = ((r + radius)[:, None, :] < dist[:, :, None]) & ~own[:, None, :]
    return _Cover(az[:, None, :], half[:, None, :], lo[:, None, :], hi[:, None, :], front)


def _mixture_ln(d2: FloatArray, ln_det: FloatArray, dim: FloatArray, model: TrackModel) -> FloatArray:
    """ln of the Gaussian-plus-outlier density with Mahalanobis distance² ``d2`` (dimension ``dim``)."""
    eps, k2 = model.outlier_prob, model.outlier_scale**2
    core = -0.5 * (d2 + ln_det + dim * LN_2PI)
    wide = -0.5 * (d2 / k2 + ln_det + dim * (math.log(k2) + LN_2PI))
    return np.asarray(np.logaddexp(math.log(1.0 - eps) + core, math.log(eps) + wide), dtype=np.float64)


def score_views(
    views: Views,
    blobs: Subset,
    tracks: Sequence[TrackRecord],
    table: TrackTable,
    vis: Visibility,
    *,
    model: TrackModel,
    max_range_m: float,
    looks: Looks,
) -> list[ViewScores]:
    """The ``blobs`` of ``views`` against every track, one :class:`ViewScores` per view of ``blobs.rows`` (see the
    module docstring); ``vis``: what every view should see of each track; ``tracks``: their links, ``looks``: their
    looks (both row for row with ``table``); nobody is seen farther than ``max_range_m``."""
    vis = Visibility(*(blobs.pick(part) for part in vis))
    p_detect = vis.p_detect
    n, m = table.n, len(blobs.entries)
    ln_miss = np.log1p(-np.minimum(p_detect, 1.0 - 1e-9))
    if n == 0 or m == 0:
        return [
            ViewScores(np.full((n, k), -np.inf), ln_miss[i], p_detect[i]) for i, k in enumerate(blobs.counts.tolist())
        ]
    col = blobs.row_of  # each blob's view: (s, n) per-view quantities become (n, m) per-blob ones by [col].T
    per_view = table.xy.ndim == PER_VIEW_NDIM  # each view's own place of each track
    d = (blobs.pick(table.xy) if per_view else table.xy[None, :, :]) - blobs.pick(views.origin)[:, None, :]
    r2 = np.maximum(d[:, :, 0] ** 2 + d[:, :, 1] ** 2, MIN_RANGE_M**2)
    dist = np.sqrt(r2)
    jac = np.stack([-d[:, :, 1] / r2, d[:, :, 0] / r2], axis=2)  # d bearing / d position
    unit = d / dist[:, :, None]  # d distance / d position
    pc = blobs.pick(table.pos_cov) if per_view else table.pos_cov
    s_tt = quadratic_form(jac, pc, jac) + bearing_var(views, blobs.rows[:, None], dist)
    s_dd_track = quadratic_form(unit, pc, unit)
    bearing, cut_var = _blob_bearings(views, blobs, dist[col].T)
    blob_s_tt = s_tt[col].T + cut_var
    nu_t = wrap_angle(bearing - np.arctan2(d[:, :, 1], d[:, :, 0])[col].T)
    d2 = nu_t**2 / blob_s_tt
    gate = d2 <= model.gate_sigmas**2
    ln_clutter = np.log(np.maximum(model.clutter_per_view, blobs.counts) / blobs.pick(views.fov_width_rad))[col]
    has = np.isfinite(blobs.take(views.mono_range_m))
    feet: tuple[FloatArray, FloatArray, FloatArray] | None = None
    density_gate = gate
    if has.any():
        s_td = quadratic_form(jac, pc, unit)[col].T
        feet, density_gate, gate = _feet_gates(
            views,
            blobs,
            (s_dd_track[col].T, s_td, dist[col].T),
            gate,
            nu_t=nu_t,
            blob_s_tt=blob_s_tt,
            vis=vis,
            model=model,
        )
        ln_clutter = ln_clutter + np.where(has, -math.log(max_range_m), 0.0)
    # Other people's blobs near the track are the alternative explanation of a blob there: the local density of
    # blobs in each track's gate beyond the one it would have (non-parametric PDA), when above the view's mean.
    counted = np.concatenate([np.zeros((n, 1)), np.cumsum(density_gate, axis=1, dtype=np.float64)], axis=1)
    in_gate = counted[:, blobs.offsets[1:]] - counted[:, blobs.offsets[:-1]]
    local = np.log(np.maximum(in_gate - 1.0, 1e-9) / (2.0 * model.gate_sigmas * np.sqrt(s_tt.T)))
    # The likelihood ratio where it can be finite: (track, blob) entries in the gate of a track the view can see.
    track, blob = np.nonzero(gate & (p_detect[col].T > 0))
    view = col[blob]
    ln_g = _mixture_ln(d2[track, blob], np.log(s_tt[view, track]), np.ones(len(track)), model)
    if feet is not None:
        nu_d, s_cond, dist_pred = (a[track, blob] for a in feet)
        cut = feet_cut_prob(vis.feet_hidden[view, track], model)
        outlier = (model.outlier_prob, model.outlier_scale)
        reach, near = vis.cut_reach_m[view, track], vis.cover_near_m[view, track]
        ln_feet = np.logaddexp(*feet_ln(nu_d, s_cond, dist_pred, cut, outlier, reach=reach, near=near))
        ln_g = ln_g + np.where(has[blob], ln_feet, 0.0)
    ln_alt = np.maximum(ln_clutter[blob], local[track, view])
    entry = np.log(np.maximum(p_detect[view, track], 1e-300)) + ln_g - ln_alt
    entry = entry + _height_term(
        views, table, track, blobs.entries[blob], dist=dist[view, track], s_dd=s_dd_track[view, track], model=model
    )
    entry = entry + _colour_term(views, blobs, looks, track, blob, model=model)
    entry = entry + _link_term(views, blobs, tracks, track, blob, model=model)
    ln_lr = np.full((n, m), -np.inf)
    ln_lr[track, blob] = entry
    return [ViewScores(lr, ln_miss[i], p_detect[i]) for i, lr in enumerate(blobs.split(ln_lr))]


def _blob_bearings(views: Views, blobs: Subset, dist: FloatArray) -> tuple[FloatArray, FloatArray]:
    """The bearings of ``blobs`` as of a person at ``dist`` ((n, m): each track's) from their cameras, and the
    variance that adds (:func:`cut_bearing`; blobs the picture's side does not cut as they are)."""
    bearing = blobs.take(views.bearing_rad)[None, :]
    side_cut = blobs.take(views.side_cut)
    if not side_cut.any():
        return bearing, np.zeros_like(bearing)
    return cut_bearing(bearing, blobs.take(views.width_rad)[None, :], side_cut[None, :], dist)


def _feet_gates(
    views: Views,
    blobs: Subset,
    track: tuple[FloatArray, FloatArray, FloatArray],
    gate: BoolArray,
    *,
    nu_t: FloatArray,
    blob_s_tt: FloatArray,
    vis: Visibility,
    model: TrackModel,
) -> tuple[tuple[FloatArray, FloatArray, FloatArray], BoolArray, BoolArray]:
    """The floor distance given the bearing (conditioned on its innovation), with its own outlier model: a box
    whose bottom is not the feet (someone nearer hides them) puts the person farther than they are, or, where the
    view's blobs merge people who overlap, nearer (the bottom of a blob that took the nearer one in).

    ``track``, all (track, blob): the track's distance variance, its bearing-distance covariance and its predicted
    distance. Returns the feet terms (innovation, conditional variance, predicted distance), the gate that counts
    blobs for the local density, and the gate of the likelihood ratio."""
    s_dd_track, s_td, dist = track
    col = blobs.row_of
    view = blobs.take(views.view_of)
    mono = blobs.take(views.mono_range_m)
    has = np.isfinite(mono)
    rng = np.where(has, mono, 0.0)
    feet_var = (
        np.where(has, blobs.take(views.mono_sigma_m), 1.0) ** 2 + views.sigma_xy_m[view] ** 2 + views.point_var_m2[view]
    )
    s_dd = s_dd_track + feet_var[None, :]
    range_innovation = rng[None, :] - dist
    nu_d = range_innovation - s_td / blob_s_tt * nu_t
    s_cond = np.maximum(s_dd - s_td**2 / blob_s_tt, 1e-18)
    near = np.abs(range_innovation) <= model.gate_sigmas * np.sqrt(s_dd)
    # Farther than the gate wherever the likelihood admits a box cut above the feet: with someone nearer or a
    # camera's body in front (``feet_cut_prob_covered``), and, less likely, with nothing known there
    # (``feet_hidden_prob``: furniture, a bag, someone untracked); the likelihood weighs which it is.
    far = (nu_d > 0) & (feet_cut_prob(vis.feet_hidden, model) > 0.0)[col].T
    cut_ok = (vis.feet_hidden > HALF)[col].T
    # Nearer than the gate only where such a blob may end at a cover's foot, and no nearer than that foot.
    cover = vis.cover_near_m[col].T
    reach_near = cover - model.gate_sigmas * np.sqrt(feet_var)[None, :]
    closer = (nu_d < 0) & cut_ok & (cover > 0) & (rng[None, :] >= reach_near)
    density_gate = gate & np.where(has[None, :], near, True)
    gate = gate & np.where(has[None, :], near | far | closer, True)
    return (nu_d, s_cond, dist), density_gate, gate


def feet_cut_prob(feet_hidden: FloatArray, model: TrackModel) -> FloatArray:
    """Probability that a box's bottom is not the person's feet: ``feet_hidden_prob`` where nothing stands in
    front, rising to ``feet_cut_prob_covered`` with the share of the feet hidden (:attr:`Visibility.feet_hidden`)."""
    return np.asarray(
        model.feet_hidden_prob + (model.feet_cut_prob_covered - model.feet_hidden_prob) * feet_hidden,
        dtype=np.float64,
    )


def feet_ln(
    nu: FloatArray,
    var: FloatArray,
    dist: FloatArray,
    cut: FloatArray,
    outlier: tuple[float, float],
    *,
    reach: FloatArray | None = None,
    near: FloatArray | None = None,
) -> tuple[FloatArray, FloatArray]:
    """ln of the density of a floor distance's innovation ``nu`` (variance ``var``, given the bearing's) for a
    person predicted ``dist`` away, as its two parts: the box shows the feet (Gaussian with the wide outlier
    part), or, with probability ``cut``, a box cut above the feet, which puts them farther: by up to ``reach -
    dist`` (uniformly, widened by two σ) where the covers' tops bound how far (``reach``:
    :attr:`Visibility.cut_reach_m`), else by an exponentially distributed distance of mean ``dist``. Where a merged
    blob may end at a nearer cover's foot (``near`` > 0: :attr:`Visibility.cover_near_m`), that chance is shared
    half and half between the cut box and such a blob, which reads anywhere from that foot to the person (uniformly,
    widened by two σ).
    ``outlier``: (probability, scale) of the wide part."""
    eps, k2 = outlier[0], outlier[1] ** 2
    core = -0.5 * (nu * nu / var + np.log(var) + LN_2PI)
    wide = -0.5 * (nu * nu / (k2 * var) + np.log(k2 * var) + LN_2PI)
    normal = np.logaddexp(math.log(1.0 - eps) + core, math.log(eps) + wide)
    scale = np.maximum(dist, MIN_RANGE_M)
    farther = np.where(nu > 0, -nu / scale - np.log(scale), -np.inf)
    if reach is not None:
        span = np.maximum(reach - dist, 0.0) + 2.0 * np.sqrt(var)
        bounded = np.isfinite(span) & (reach > 0.0)
        span = np.where(bounded, span, 1.0)
        farther = np.where(bounded, np.where((nu > 0) & (nu <= span), -np.log(span), -np.inf), farther)
    if near is not None:
        merged = near > 0.0
        span_near = np.maximum(dist - near, 0.0) + 2.0 * np.sqrt(var)
        nearer = np.where(merged & (nu < 0) & (nu >= -span_near), -np.log(span_near), -np.inf)
        half = np.where(merged, LN_HALF, 0.0)
        farther = np.logaddexp(half + farther, half + nearer)
    cut = np.clip(cut, 1e-300, 1.0 - 1e-9)
    return np.log1p(-cut) + normal, np.log(cut) + farther


def _height_term(
    views: Views,
    table: TrackTable,
    track: IntArray,
    entry: IntArray,
    *,
    dist: FloatArray,
    s_dd: FloatArray,
    model: TrackModel,
) -> FloatArray:
    """ln [N(implied head height; track height) · height_range] of each (``track``, blob ``entry``) pair: the paper's
    height consistency (``dist``, ``s_dd``: the track's distance and its variance from the blob's camera)."""
    view = views.view_of[entry]
    tan_top = np.tan(views.top_elev_rad[entry])
    sec2 = 1.0 + tan_top**2
    z = views.z_m[view] + dist * tan_top
    var = (
        table.height_var[track]
        + (dist * views.sigma_rad[view] * sec2) ** 2
        + (tan_top**2) * s_dd
        + views.point_var_m2[view]
    )
    nu = z - table.height[track]
    term = -0.5 * (nu**2 / var + np.log(var) + LN_2PI) + math.log(model.height_range_m)
    # A head above the picture gives only a lower bound: no evidence either way.
    return np.asarray(
        np.where(views.top_cut[entry], 0.0, np.maximum(term, math.log(model.outlier_prob))), dtype=np.float64
    )


def _colour_term(
    views: Views, blobs: Subset, looks: Looks, track: IntArray, blob: IntArray, *, model: TrackModel
) -> FloatArray:
    """ln [p(colour | this person) / p(colour | anyone else)] of each (``track``, ``blob``) pair (``blob``: a
    position in ``blobs``), the paper's
    intensity similarity, twice:

    * against the track's own look in this view, once it has one (the same shirt, from this side, over time);
    * against its look in the *other* views (the paper's r_is compares the blobs of two views): a track whose
      views show different people (a ghost where two people's rays cross) matches neither well.

    0 where the track has no look to compare, or the view no histograms.
    """
    out = np.zeros(len(track))
    view, entry = blobs.row_of[blob], blobs.entries[blob]
    blob_bins = views.hist_bins[views.view_of[entry]]
    for bins, hist in views.hist_sqrt.items():
        own, own_ok, total, count = looks.by_bins[bins]
        own, own_ok = own[:, blobs.rows], own_ok[:, blobs.rows]
        # The other views' looks: all learnt ones but this view's, their mean renormalised (a unit vector's
        # direction).
        others = total[:, None, :] - own * own_ok[:, :, None]
        others_ok = count[:, None] - own_ok > 0
        norm = np.linalg.norm(others, axis=2)
        others = others / np.maximum(norm, 1e-12)[:, :, None]
        here = blob_bins == bins
        t, v, h = track[here], view[here], hist[entry[here]]
        # Bhattacharyya coefficients of each blob with the track's looks in the blob's view.
        bc_own = np.einsum("ek,ek->e", own[t, v], h)
        bc_others = np.einsum("ek,ek->e", others[t, v], h)
        term = np.where(own_ok[t, v] > 0, colour_ln_lr(bc_own, model.colour_sigma, model.outlier_prob), 0.0)
        out[here] = term + np.where(
            others_ok[t, v], colour_ln_lr(bc_others, model.colour_sigma, model.outlier_prob), 0.0
        )
    return out


def _look_arrays(
    tracks: Sequence[TrackRecord], views: Views, bins: int, min_s: float
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Each track's looks learnt for at least ``min_s``: (n, s, bins) in each view of ``views`` and (n, s) 1/0
    whether it has one there, and the (n, bins) sum and (n,) count over every view it has one in (those of cameras
    not in ``views`` too)."""
    # (track, view row or -1, look) of each look learnt, as three lists (one pass over every track's looks).
    track_of: list[int] = []
    view_of: list[int] = []
    learnt: list[FloatArray] = []
    shape, view_row = (bins,), views.rows.get
    for i, tr in enumerate(tracks):
        look_s = tr.look_s
        for sid, look in tr.looks.items():
            if look.shape == shape and look_s.get(sid, 0.0) >= min_s:
                track_of.append(i)
                view_of.append(view_row(sid, -1))
                learnt.append(look)
    n, s = len(tracks), views.n_views
    own = np.zeros((n * s, bins))
    own_ok = np.zeros(n * s)
    if not learnt:
        return own.reshape(n, s, bins), own_ok.reshape(n, s), np.zeros((n, bins)), np.zeros(n)
    row = np.array(track_of, dtype=np.int64)
    col = np.array(view_of, dtype=np.int64)
    mat = np.concatenate(learnt).reshape(-1, bins)
    here = col >= 0
    own[row[here] * s + col[here]] = mat[here]
    own_ok[row[here] * s + col[here]] = 1.0
    # Each track's looks in its own slots, in its order: summed one after the other.
    count = np.bincount(row, minlength=n)
    slot = np.arange(len(learnt)) - (np.cumsum(count) - count)[row]
    each = np.zeros((n * int(count.max()), bins))
    each[row * int(count.max()) + slot] = mat
    total = each.reshape(n, -1, bins).sum(axis=1)
    return own.reshape(n, s, bins), own_ok.reshape(n, s), total, count.astype(np.float64)


def _link_term(
    views: Views, blobs: Subset, tracks: Sequence[TrackRecord], track: IntArray, blob: IntArray, *, model: TrackModel
) -> FloatArray:
    """ln(link_odds) of each (``track``, ``blob``) pair (``blob``: a position in ``blobs``) where the blob continues
    the node's 2D track last assigned to the track, else 0."""
    sids = [views.sensor_ids[r] for r in blobs.rows.tolist()]
    linked = np.array([[tr.links.get(sid, -1) for sid in sids] for tr in tracks], dtype=np.int64)
    linked = linked.reshape(len(tracks), len(sids))[track, blobs.row_of[blob]]
    same = (linked == views.local_id[blobs.entries[blob]]) & (linked >= 0)
    return np.where(same, math.log(model.link_odds), 0.0)
