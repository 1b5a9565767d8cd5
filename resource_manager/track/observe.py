"""What each camera should see of each track, and how well each of its blobs fits: one cost for assignment.

For a view and the predicted tracks this computes, for every (track, blob), the log likelihood ratio of "this
blob is that person" against "this blob is a false detection", and for every track the log likelihood of "the
view missed that person". The ratio multiplies independent terms:

* **position**: the blob's bearing and, where a perspective camera sees the feet, its floor distance, against
  the track's predicted bearing and distance; the innovation covariance is the track's position covariance
  seen from the camera plus the measurement's own (the sensor's bearing error, the pose's error, the spread of
  the point seen around the person's floor position). The density is a Gaussian with a wider outlier
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
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from resource_manager.track.model import PERSON_RADIUS_M, TrackModel
from resource_manager.track.motion import MIN_RANGE_M, Observation
from resource_manager.track.state import TrackRecord
from resource_manager.views.blobs import ViewBlobs

__all__ = ["Spread", "TrackTable", "ViewScores", "observation", "observation_rows", "score_view", "visibility"]

FloatArray = npt.NDArray[np.float64]
TWO_PI = 2.0 * math.pi
LN_2PI = math.log(TWO_PI)


@dataclass(frozen=True, slots=True)
class Spread:
    """Variances (m²) of a camera's measured points around a person: across its rays, and along them (feet)."""

    cross_var: float
    range_var: float


@dataclass(frozen=True, slots=True)
class TrackTable:
    """The predicted tracks as arrays (built once per tick, shared by every view)."""

    xy: FloatArray
    """(n, 2) positions."""
    pos_cov: FloatArray
    """(n, 2, 2) position covariances."""
    height: FloatArray
    """(n,) head-top heights."""
    height_var: FloatArray
    looks: dict[tuple[int, str], tuple[FloatArray, FloatArray]] = field(default_factory=dict)
    """Colour looks as arrays, filled on first use (see :func:`_look_arrays`)."""

    @staticmethod
    def of(tracks: list[TrackRecord]) -> TrackTable:
        n = len(tracks)
        if n == 0:
            return TrackTable(np.zeros((0, 2)), np.zeros((0, 2, 2)), np.zeros(0), np.zeros(0))
        return TrackTable(
            xy=np.array([tr.x[:2] for tr in tracks], dtype=np.float64),
            pos_cov=np.array([tr.p[:2, :2] for tr in tracks], dtype=np.float64),
            height=np.array([tr.height_m for tr in tracks], dtype=np.float64),
            height_var=np.array([tr.height_var for tr in tracks], dtype=np.float64),
        )


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


def _wrap(a: FloatArray) -> FloatArray:
    return np.asarray(np.remainder(a + math.pi, TWO_PI) - math.pi, dtype=np.float64)


def fov_width(v: ViewBlobs) -> float:
    """Horizontal extent of the view's bearings (rad)."""
    return TWO_PI if v.fov is None else min(2.0 * v.fov[1], TWO_PI)


def visibility(
    v: ViewBlobs, table: TrackTable, model: TrackModel, occluders: npt.NDArray[np.bool_] | None = None
) -> FloatArray:
    """(n,) detection probability of each track in this view: 0 out of its picture or range, lower when
    someone nearer stands on the same bearing (``occluders``: which rows may hide others; default all)."""
    n = table.xy.shape[0]
    if n == 0:
        return np.zeros(0)
    d = table.xy - v.origin_xy
    dist = np.hypot(d[:, 0], d[:, 1])
    seen = (dist > MIN_RANGE_M) & (dist <= model.max_range_m)
    if v.image is not None:
        feet = np.column_stack([table.xy, np.zeros(n)])
        head = np.column_stack([table.xy, table.height])
        seen &= v.image.inside(feet) | v.image.inside(head)
    elif v.fov is not None:
        seen &= np.abs(_wrap(np.arctan2(d[:, 1], d[:, 0]) - v.fov[0])) <= v.fov[1]
    p = np.where(seen, model.p_detect, 0.0)
    if n > 1:
        covered = _covered(v, table, dist, seen if occluders is None else seen & occluders)
        p = np.where(seen, model.p_detect_hidden + (model.p_detect - model.p_detect_hidden) * (1.0 - covered), 0.0)
    return p


def _covered(v: ViewBlobs, table: TrackTable, dist: FloatArray, blockers: npt.NDArray[np.bool_]) -> FloatArray:
    """(n,) share of each person's silhouette (feet to head, one person wide) that nearer people cover in the
    picture, treating the covers as independent: 1 - Π(1 - overlap_k / area).

    Angular rectangles: azimuth ± person radius / distance, elevation from the feet to the head top. A camera
    above the crowd sees the head of someone behind a nearer person; one at head height does not.
    """
    d = table.xy - v.origin_xy
    az = np.arctan2(d[:, 1], d[:, 0])
    r = np.maximum(dist, MIN_RANGE_M)
    half = PERSON_RADIUS_M / r
    lo = np.arctan2(-v.z_m, r)
    hi = np.arctan2(table.height - v.z_m, r)
    width = np.maximum(np.minimum(half[:, None], half[None, :]) * 2.0, 0.0)
    over_az = np.clip(half[:, None] + half[None, :] - np.abs(_wrap(az[:, None] - az[None, :])), 0.0, width)
    over_el = np.clip(np.minimum(hi[:, None], hi[None, :]) - np.maximum(lo[:, None], lo[None, :]), 0.0, None)
    area = np.maximum(2.0 * half * (hi - lo), 1e-12)
    # [i, k]: k stands in front of i (nearer by more than a person's depth) and can hide.
    front = (dist[None, :] < dist[:, None] - 2.0 * PERSON_RADIUS_M) & blockers[None, :]
    share = np.where(front, np.minimum(over_az * over_el / area[:, None], 1.0), 0.0)
    return np.asarray(1.0 - np.prod(1.0 - share, axis=1), dtype=np.float64)


def _mixture_ln(d2: FloatArray, ln_det: FloatArray, dim: FloatArray, model: TrackModel) -> FloatArray:
    """ln of the Gaussian-plus-outlier density with Mahalanobis distance² ``d2`` (dimension ``dim``)."""
    eps, k2 = model.outlier_prob, model.outlier_scale**2
    core = -0.5 * (d2 + ln_det + dim * LN_2PI)
    wide = -0.5 * (d2 / k2 + ln_det + dim * (math.log(k2) + LN_2PI))
    return np.asarray(np.logaddexp(math.log(1.0 - eps) + core, math.log(eps) + wide), dtype=np.float64)


def score_view(
    v: ViewBlobs,
    tracks: list[TrackRecord],
    table: TrackTable,
    p_detect: FloatArray,
    *,
    model: TrackModel,
    spread: Spread,
) -> ViewScores:
    """Every blob of ``v`` against every track (see the module docstring); ``spread``: the camera's own spread of
    points around a person."""
    n, m = table.xy.shape[0], v.n
    ln_miss = np.log1p(-np.minimum(p_detect, 1.0 - 1e-9))
    if n == 0 or m == 0:
        return ViewScores(np.full((n, m), -np.inf), ln_miss, p_detect)
    d = table.xy - v.origin_xy
    r2 = np.maximum(d[:, 0] ** 2 + d[:, 1] ** 2, MIN_RANGE_M**2)
    dist = np.sqrt(r2)
    jac = np.column_stack([-d[:, 1] / r2, d[:, 0] / r2])  # d bearing / d position
    unit = d / dist[:, None]  # d distance / d position
    pc = table.pos_cov
    s_tt = np.einsum("ni,nij,nj->n", jac, pc, jac) + bearing_var(v, dist, spread)
    s_dd_track = np.einsum("ni,nij,nj->n", unit, pc, unit)
    s_td = np.einsum("ni,nij,nj->n", jac, pc, unit)
    nu_t = _wrap(v.bearing_rad[None, :] - np.arctan2(d[:, 1], d[:, 0])[:, None])
    d2 = nu_t**2 / s_tt[:, None]
    gate = d2 <= model.gate_sigmas**2
    ln_det = np.broadcast_to(np.log(s_tt)[:, None], (n, m)).copy()
    dim = np.ones((n, m))
    ln_clutter = np.full(m, math.log(max(model.clutter_per_view, float(m)) / fov_width(v)))
    if v.mono_range_m is not None and v.mono_sigma_m is not None:
        has = np.isfinite(v.mono_range_m)
        if has.any():
            rng = np.where(has, v.mono_range_m, 0.0)
            feet_var = np.where(has, v.mono_sigma_m, 1.0) ** 2 + v.sigma_xy_m**2 + spread.range_var
            s_dd = s_dd_track[:, None] + feet_var[None, :]
            nu_d = rng[None, :] - dist[:, None]
            det = s_tt[:, None] * s_dd - s_td[:, None] ** 2
            det = np.maximum(det, 1e-18)
            d2_joint = (s_dd * nu_t**2 - 2.0 * s_td[:, None] * nu_t * nu_d + s_tt[:, None] * nu_d**2) / det
            gate_d = nu_d**2 / s_dd <= model.gate_sigmas**2
            d2 = np.where(has[None, :], d2_joint, d2)
            gate &= np.where(has[None, :], gate_d, True)
            ln_det = np.where(has[None, :], np.log(det), ln_det)
            dim = np.where(has[None, :], 2.0, dim)
            ln_clutter = ln_clutter + np.where(has, -math.log(model.max_range_m), 0.0)
    ln_g = _mixture_ln(d2, ln_det, dim, model)
    # Other people's blobs near the track are the alternative explanation of a blob there: the local density of
    # blobs in each track's gate beyond the one it would have (non-parametric PDA), when above the view's mean.
    in_gate = np.count_nonzero(gate, axis=1).astype(np.float64)
    local = np.log(np.maximum(in_gate - 1.0, 1e-9) / (2.0 * model.gate_sigmas * np.sqrt(s_tt)))
    ln_alt = np.maximum(ln_clutter[None, :], local[:, None])
    ln_lr = np.log(np.maximum(p_detect, 1e-300))[:, None] + ln_g - ln_alt
    ln_lr = ln_lr + _height_term(v, table, dist, s_dd_track, model=model, spread=spread)
    if v.hist_sqrt is not None:
        ln_lr = ln_lr + _colour_term(v, tracks, table, model)
    ln_lr = ln_lr + _link_term(v, tracks, model)
    ln_lr = np.where(gate & (p_detect > 0)[:, None], ln_lr, -np.inf)
    return ViewScores(ln_lr, ln_miss, p_detect)


def bearing_var(v: ViewBlobs, dist: FloatArray, spread: Spread) -> FloatArray:
    """(n,) bearing variance of a person at ``dist``: the sensor's and its yaw's, its position's and the
    spread of the point seen around the person."""
    d = np.maximum(dist, MIN_RANGE_M)
    return np.asarray(v.sigma_rad**2 + (spread.cross_var + v.sigma_xy_m**2) / (d * d), dtype=np.float64)


def _height_term(
    v: ViewBlobs, table: TrackTable, dist: FloatArray, s_dd: FloatArray, *, model: TrackModel, spread: Spread
) -> FloatArray:
    """(n, m) ln [N(implied head height; track height) · height_range]: the paper's height consistency."""
    tan_top = np.tan(v.top_elev_rad)
    sec2 = 1.0 + tan_top**2
    z = v.z_m + dist[:, None] * tan_top[None, :]
    var = (
        table.height_var[:, None]
        + (dist[:, None] * v.sigma_rad * sec2[None, :]) ** 2
        + (tan_top**2)[None, :] * s_dd[:, None]
        + spread.cross_var
    )
    nu = z - table.height[:, None]
    term = -0.5 * (nu**2 / var + np.log(var) + LN_2PI) + math.log(model.height_range_m)
    # A head above the picture gives only a lower bound: no evidence either way.
    cut = v.top_cut if v.top_cut is not None else np.zeros(v.n, dtype=bool)
    return np.asarray(np.where(cut[None, :], 0.0, np.maximum(term, math.log(model.outlier_prob))), dtype=np.float64)


def _colour_term(v: ViewBlobs, tracks: list[TrackRecord], table: TrackTable, model: TrackModel) -> FloatArray:
    """(n, m) ln [p(colour | this person) / p(colour | anyone else)], the paper's intensity similarity, twice:

    * against the track's own look in this view, once it has one (the same shirt, from this side, over time);
    * against its look in the *other* views (the paper's r_is compares the blobs of two views): a track whose
      views show different people (a ghost where two people's rays cross) matches neither well.

    0 where the track has no look to compare.
    """
    assert v.hist_sqrt is not None
    k = v.hist_sqrt.shape[1]
    own, own_ok = _look_arrays(tracks, table, k, v.sensor_id, model.look_min_s)
    total, count = _look_arrays(tracks, table, k, "", model.look_min_s)
    # The other views' looks: all learnt ones but this view's, their mean renormalised (a unit vector's direction).
    others = total - own * own_ok[:, None]
    others_ok = count - own_ok > 0
    norm = np.linalg.norm(others, axis=1)
    others = others / np.maximum(norm, 1e-12)[:, None]
    out = np.where(own_ok[:, None] > 0, _colour_ln_lr(own, v.hist_sqrt, model), 0.0)
    return np.asarray(out + np.where(others_ok[:, None], _colour_ln_lr(others, v.hist_sqrt, model), 0.0))


def _look_arrays(
    tracks: list[TrackRecord], table: TrackTable, bins: int, sensor_id: str, min_s: float
) -> tuple[FloatArray, FloatArray]:
    """(n, bins) looks and (n,) 1/0 whether each track has one, learnt for at least ``min_s``: in view
    ``sensor_id``, or (``""``) the sum and count over every view. Computed once per tick per view."""
    key = (bins, sensor_id)
    got = table.looks.get(key)
    if got is not None:
        return got
    n = len(tracks)
    mat = np.zeros((n, bins))
    ok = np.zeros(n)
    for i, tr in enumerate(tracks):
        items = tr.looks.items() if not sensor_id else [(sensor_id, tr.looks.get(sensor_id))]
        for sid, look in items:
            if look is not None and look.shape == (bins,) and tr.look_s.get(sid, 0.0) >= min_s:
                mat[i] += look
                ok[i] += 1.0
    table.looks[key] = (mat, ok)
    return mat, ok


def _colour_ln_lr(looks: FloatArray, hist_sqrt: FloatArray, model: TrackModel) -> FloatArray:
    """(n, m) ln of the half-normal density of the Bhattacharyya distance (spread ``colour_sigma``) with an
    outlier floor, against a uniform distance for anyone else; ``looks`` (n, k), ``hist_sqrt`` (m, k)."""
    dist = 1.0 - np.clip(looks @ hist_sqrt.T, 0.0, 1.0)
    sig, eps = model.colour_sigma, model.outlier_prob
    same = 2.0 / (sig * math.sqrt(TWO_PI)) * np.exp(-0.5 * (dist / sig) ** 2)
    return np.asarray(np.log((1.0 - eps) * same + eps), dtype=np.float64)


def _link_term(v: ViewBlobs, tracks: list[TrackRecord], model: TrackModel) -> FloatArray:
    """(n, m) ln(link_odds) where the blob continues the node's 2D track last assigned to the track."""
    linked = np.array([tr.links.get(v.sensor_id, -1) for tr in tracks], dtype=np.int64)
    same = linked[:, None] == v.local_id[None, :]
    return np.where(same & (linked[:, None] >= 0), math.log(model.link_odds), 0.0)


def observation(v: ViewBlobs, j: int, xy: FloatArray, spread: Spread, weight: float = 1.0) -> Observation:
    """Blob ``j`` of view ``v`` as an :class:`Observation` of a person near ``xy``.

    ``weight`` in (0, 1]: the share of a new frame's information this observation carries (a tick between two
    frames sees an interpolation of frames already used): its variances are divided by it.
    """
    d = math.hypot(float(xy[0] - v.origin_xy[0]), float(xy[1] - v.origin_xy[1]))
    var = float(bearing_var(v, np.array([d]), spread)[0]) / weight
    rng = rvar = math.nan
    if v.mono_range_m is not None and v.mono_sigma_m is not None and math.isfinite(float(v.mono_range_m[j])):
        rng = float(v.mono_range_m[j])
        rvar = (float(v.mono_sigma_m[j]) ** 2 + v.sigma_xy_m**2 + spread.range_var) / weight
    return Observation((float(v.origin_xy[0]), float(v.origin_xy[1])), float(v.bearing_rad[j]), var, rng, rvar)


def observation_rows(
    v: ViewBlobs, blobs: npt.NDArray[np.int64], xy: FloatArray, spread: Spread, weight: float = 1.0
) -> FloatArray:
    """:func:`observation` of many blobs of one view at once, each of a person near its row of ``xy`` (n, 2): (n, 6)
    rows of origin x, y, bearing, its variance, floor distance (NaN: none), its variance, as
    :meth:`~resource_manager.track.motion.ObservationBatch.padded` takes them."""
    n = len(blobs)
    out = np.empty((n, 6))
    out[:, 0], out[:, 1] = v.origin_xy[0], v.origin_xy[1]
    out[:, 2] = v.bearing_rad[blobs]
    d = np.hypot(xy[:, 0] - v.origin_xy[0], xy[:, 1] - v.origin_xy[1])
    out[:, 3] = bearing_var(v, d, spread) / weight
    out[:, 4:] = math.nan
    if v.mono_range_m is not None and v.mono_sigma_m is not None:
        rng = v.mono_range_m[blobs]
        has = np.isfinite(rng)
        out[has, 4] = rng[has]
        out[has, 5] = (v.mono_sigma_m[blobs][has] ** 2 + v.sigma_xy_m**2 + spread.range_var) / weight
    return out
