"""3D blob-based stereo match (paper, "3D Blob-Based Stereo Match", Eq. 7).

For two cameras with known poses, every blob i of camera a is scored against
every blob j of camera b::

    r(i, j) = r_is(i, j) · r_rc(i, j) · r_wc(i, j) · r_hc(i, j)      (Eq. 7)

* r_is: colour similarity, the Bhattacharyya coefficient of the histograms;
* r_rc: ray convergence; soft, from the smallest inner angle of the triangle
  O1-O2-T against the bearing error, with a colinear branch where the
  size-ratio method (Eq. 2) takes over (docs/geometry.md §4);
* r_wc: width consistency of the metric widths W_k = 2 D_k tan(w_k / 2);
* r_hc: height consistency of the head-top heights H_k = z_k + D_k tan(top_k).

The paper adds a temporal consistency term from the tracks to each r(i, j);
here tracking history enters earlier: the tracker assigns each view's blobs to
the tracks' predictions first (resource_manager/track/observe.py), and Eq. 7
pairs only the blobs no track explains, for which no track has a say. Two
matchers turn the matrix into pairs, chosen by name (docs/STYLE.md habit 12): ``greedy`` (the
paper's: repeatedly take the largest entry; one sort of the entries above the
threshold gives the same pairs) and ``global`` (Hungarian on the sum of
confidences, with a private "unmatched" dummy per row and column).

:func:`match_matrices` scores many camera pairs in one vectorised pass, on the
tick's :class:`~resource_manager.views.blobs.Views` (each view with only some of
its blobs: a :class:`~resource_manager.views.blobs.Subset`); with 16 cameras and
20 people it is the largest single stage of a manager tick.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Final

import numpy as np
import numpy.typing as npt
from scipy.special import ndtr

from common.angles import wrap_angle
from common.arrays import BoolArray, FloatArray, IntArray
from common.errors import GeometryError
from common.geometry import MIN_SIN, size_ratio
from resource_manager.config import MatchSection, default_of
from resource_manager.stereo.match_tables import Tables, colour_table
from resource_manager.stereo.matchers import MATCHERS, GlobalMatcher, GreedyMatcher, Matcher, get_matcher
from resource_manager.views.blobs import Subset, Views

__all__ = [
    "MATCHERS",
    "GlobalMatcher",
    "GreedyMatcher",
    "MatchMatrix",
    "MatchParams",
    "Matcher",
    "get_matcher",
    "match_matrices",
    "match_matrix",
]

FEET_SIGMAS: Final = 4.0
"""The feet's floor check allows this many bearing errors times the distance (a box bottom is coarser than a
head bearing)."""


@dataclass(frozen=True, slots=True)
class MatchParams:
    """The knobs of Eq. 7: ``[match]``'s are defaulted and documented in
    :class:`resource_manager.config.MatchSection`."""

    max_range_m: float = default_of(MatchSection, "max_range_m")
    width_sigma: float = default_of(MatchSection, "width_sigma")
    height_sigma: float = default_of(MatchSection, "height_sigma")
    use_colour: bool = default_of(MatchSection, "use_colour")
    floor_sigma_m: float = default_of(MatchSection, "floor_sigma_m")
    width_floor: float = default_of(MatchSection, "width_floor")
    colinear_sigmas: float = 2.0
    """A target within this many bearing sigmas (or its own half width) of the baseline is size-ratio."""


@dataclass(frozen=True, slots=True)
class MatchMatrix:
    """Eq. 7 for every blob pair of two views, and the hypothesised targets."""

    r: FloatArray
    """(na, nb) total confidence."""
    d1_m: FloatArray
    d2_m: FloatArray
    xy: FloatArray
    """(na, nb, 2) hypothesised target positions."""
    size_ratio: BoolArray
    """(na, nb) True where Eq. 2 (size-ratio) was used instead of Eq. 1."""
    parts: dict[str, FloatArray]
    """The factors r_is, r_rc, r_wc, r_hc (for tests and diagnostics)."""


def _log_ratio_score(v1: FloatArray, v2: FloatArray, sigma: float) -> FloatArray:
    """exp(-ln²(v1/v2) / 2σ²); 0 where either value is not positive."""
    ok = (v1 > 0) & (v2 > 0)
    if ok.all():  # the usual case: the same arithmetic without the masks
        lr = np.log(v1 / v2)
        return np.asarray(np.exp(-(lr**2) / (2.0 * sigma**2)), dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        lr = np.where(ok, np.log(np.where(ok, v1, 1.0) / np.where(ok, v2, 1.0)), 0.0)
    return np.where(ok, np.exp(-(lr**2) / (2.0 * sigma**2)), 0.0)


def match_matrix(views: Views, a: int, b: int, params: MatchParams) -> MatchMatrix:
    """Score every blob of view ``a`` (camera 1, O1) against every blob of view ``b`` (camera 2, O2) (Eq. 7)."""
    return match_matrices(views, [(a, b)], params)[0]


@dataclass(slots=True)
class _Batch:
    """The pairs' per-blob inputs, padded to the largest blob counts, with a leading pair axis p."""

    nas: list[int]
    nbs: list[int]
    shape: tuple[int, int, int]
    rows: IntArray
    """Every view (row) of the batch once."""
    tabs: Tables
    ia: IntArray
    """(p,) index in ``rows`` of each pair's camera 1 (O1)..."""
    ib: IntArray
    """...and of its camera 2 (O2)."""
    per_blob: FloatArray
    """(v, n, c) bearing, width, top (and with the floor term bottom) elevations of every view's blobs."""
    tan_w: FloatArray
    tan_top: FloatArray
    cut: BoolArray
    z_view: FloatArray
    o1: FloatArray
    base: FloatArray
    """(p, 1, 1) baseline lengths B."""
    psi12: FloatArray
    sigma: FloatArray
    """(p, 1, 1) the pair's bearing error (at least 1e-6 rad)."""
    th1: FloatArray
    """(p, na, 1) camera 1's bearings."""
    th2: FloatArray
    """(p, 1, nb) camera 2's bearings."""


@dataclass(slots=True)
class _Rays:
    """Eqs. 1-2 on every blob pair: inner angles, the method, and the distances where the rays meet in range."""

    abs1: FloatArray
    abs2: FloatArray
    same_side: BoolArray
    converge: BoolArray
    pi1: FloatArray
    col_d: FloatArray
    """How far from colinear with the baseline (rad)."""
    use_sr: BoolArray
    """Eq. 2 (size-ratio) rather than Eq. 1."""
    d1: FloatArray
    d2: FloatArray
    valid: BoolArray
    """Both distances positive and within ``max_range_m``."""


def _gather(views: Views, blobs: Subset, pairs: Sequence[tuple[int, int]], floor: bool) -> _Batch:
    """The per-view tables, gathered per pair (each view padded once however many pairs share it)."""
    counts = blobs.counts.tolist()
    nas = [counts[a] for a, _ in pairs]
    nbs = [counts[b] for _, b in pairs]
    na, nb = max(*nas, 1), max(*nbs, 1)
    index: dict[int, int] = {}  # position in ``blobs.rows`` -> in the batch, in order of first use
    for a, b in pairs:
        for v in (a, b):
            index.setdefault(v, len(index))
    rows = blobs.rows[list(index)]
    tabs = Tables(views, rows.tolist(), [blobs.part(v) for v in index], max(na, nb))
    ia = np.array([index[a] for a, _ in pairs], dtype=np.int64)
    ib = np.array([index[b] for _, b in pairs], dtype=np.int64)
    columns = [views.bearing_rad, views.width_rad, views.top_elev_rad]
    if floor:
        columns.append(views.bottom_elev_rad)
    per_blob = tabs.table(columns)
    bearing, width = per_blob[:, :, 0], per_blob[:, :, 1]
    origin = views.origin[rows]
    o1, o2 = origin[ia], origin[ib]
    d = o2 - o1
    sigma_rad = views.sigma_rad[rows].tolist()
    sigma = np.maximum(
        np.array(
            [
                math.hypot(sigma_rad[a], sigma_rad[b]) / math.sqrt(2.0)
                for a, b in zip(ia.tolist(), ib.tolist(), strict=True)
            ]
        ),
        1e-6,
    )
    return _Batch(
        nas=nas,
        nbs=nbs,
        shape=(len(pairs), na, nb),
        rows=rows,
        tabs=tabs,
        ia=ia,
        ib=ib,
        per_blob=per_blob,
        tan_w=np.tan(np.nan_to_num(width) / 2.0),
        tan_top=np.tan(np.nan_to_num(per_blob[:, :, 2])),
        cut=tabs.flags(views.top_cut),
        z_view=views.z_m[rows],
        o1=o1,
        base=np.hypot(d[:, 0], d[:, 1])[:, None, None],
        psi12=np.arctan2(d[:, 1], d[:, 0])[:, None, None],
        sigma=sigma[:, None, None],
        th1=bearing[ia, :na][:, :, None],
        th2=bearing[ib, :nb][:, None, :],
    )


def _rays(g: _Batch, params: MatchParams) -> _Rays:
    """Ray geometry on every blob pair: signed inner angles at O1 and O2 (docs/geometry.md §4), then the
    distances by Eq. 2 where target and baseline are (nearly) colinear, by Eq. 1 elsewhere."""
    _, na, nb = g.shape
    a1 = wrap_angle(g.th1 - g.psi12)
    a2 = wrap_angle(g.psi12 + math.pi - g.th2)
    abs1, abs2 = np.abs(a1), np.abs(a2)
    same_side = np.sign(a1) == np.sign(a2)  # (p, na, nb) from here on
    converge = same_side & (abs1 + abs2 < math.pi)
    # Eq. 2 (size-ratio) where target and baseline are (nearly) colinear: the crossover of
    # docs/geometry.md §3, phi1 < w1·dphi/dw, taken here as "the target's image covers the epipole".
    pi1, pi2 = math.pi - abs1, math.pi - abs2
    col_d = np.minimum(np.maximum(abs1, abs2), np.minimum(np.maximum(abs1, pi2), np.maximum(pi1, abs2)))
    width = g.per_blob[:, :, 1]
    w1, w2 = width[g.ia, :na][:, :, None], width[g.ib, :nb][:, None, :]
    with np.errstate(invalid="ignore"):
        colinear_gap = np.maximum(params.colinear_sigmas * g.sigma, 0.5 * np.minimum(w1, w2))
        use_sr = col_d < colinear_gap
    d1 = np.full(g.shape, np.nan)
    d2 = np.full(g.shape, np.nan)
    _size_ratio_distances(g.base, abs1, abs2, w1=w1, w2=w2, use_sr=use_sr, d1=d1, d2=d2)
    _triangulated_distances(g.base, abs1, abs2, candidates=converge & ~use_sr & (g.base > 0), d1=d1, d2=d2)
    with np.errstate(invalid="ignore"):
        valid = (d1 > 0) & (d2 > 0) & (d1 <= params.max_range_m) & (d2 <= params.max_range_m)
    d1[~valid] = 0.0
    d2[~valid] = 0.0
    return _Rays(abs1, abs2, same_side, converge, pi1, col_d, use_sr, d1, d2, valid)


def _size_ratio_distances(
    base: FloatArray,
    abs1: FloatArray,
    abs2: FloatArray,
    *,
    w1: FloatArray,
    w2: FloatArray,
    use_sr: BoolArray,
    d1: FloatArray,
    d2: FloatArray,
) -> None:
    """Eq. 2 into ``d1``, ``d2`` where ``use_sr``, with sizes sin(w/2) (exact for a cylinder of the target's
    width); a pair Eq. 2 cannot place is taken off ``use_sr``."""
    for k, i, j in np.argwhere(use_sr):
        c1 = 1.0 if abs1[k, i, 0] < math.pi / 2 else -1.0
        c2 = 1.0 if abs2[k, 0, j] < math.pi / 2 else -1.0
        try:
            d1[k, i, j], d2[k, i, j] = size_ratio(
                float(base[k, 0, 0]), math.sin(w1[k, i, 0] / 2), math.sin(w2[k, 0, j] / 2), c1, c2
            )
        except GeometryError:
            use_sr[k, i, j] = False


def _triangulated_distances(
    base: FloatArray,
    abs1: FloatArray,
    abs2: FloatArray,
    *,
    candidates: BoolArray,
    d1: FloatArray,
    d2: FloatArray,
) -> None:
    """Eq. 1 into ``d1``, ``d2`` among ``candidates`` where the triangle is proper (common.geometry.triangulate
    on the converging pairs)."""
    kk, ii, jj = np.nonzero(candidates)
    s0 = np.sin(abs1[kk, ii, 0] + abs2[kk, 0, jj])
    proper = s0 > MIN_SIN
    kk, ii, jj, s0 = kk[proper], ii[proper], jj[proper], s0[proper]
    bb = base[kk, 0, 0]
    d1[kk, ii, jj] = bb * np.sin(abs2)[kk, 0, jj] / s0
    d2[kk, ii, jj] = bb * np.sin(abs1)[kk, ii, 0] / s0


def _convergence(g: _Batch, rays: _Rays, at: tuple[npt.NDArray[np.intp], ...]) -> FloatArray:
    """r_rc at the blob pairs ``at`` (where the rays meet in range): soft, from the smallest inner angle of the
    triangle against the bearing error; near colinear, from the distance to colinearity."""
    kk, ii, jj = at
    sig_v = g.sigma[kk, 0, 0]
    sr_v = rays.use_sr[kk, ii, jj]
    phi0 = rays.pi1[kk, ii, 0] - rays.abs2[kk, 0, jj]
    v1, v2 = rays.abs1[kk, ii, 0], rays.abs2[kk, 0, jj]
    margin = np.where(
        rays.converge[kk, ii, jj],
        np.minimum(np.minimum(v1, v2), phi0),
        np.where(rays.same_side[kk, ii, jj], phi0, -np.minimum(v1, v2)),
    )
    r_rc_v = ndtr(margin / (math.sqrt(2.0) * sig_v))
    if sr_v.any():
        c = rays.col_d[kk, ii, jj][sr_v]
        r_rc_v[sr_v] = np.maximum(r_rc_v[sr_v], np.exp(-(c**2) / (4.0 * sig_v[sr_v] ** 2)))
    return np.asarray(r_rc_v, dtype=np.float64)


def _heights(
    g: _Batch, rays: _Rays, at: tuple[npt.NDArray[np.intp], ...], params: MatchParams
) -> tuple[FloatArray, FloatArray]:
    """r_hc at the blob pairs ``at`` (head-top heights from each view, and the feet on the floor where
    visible), and r_hc elsewhere (no distance: the cameras' own heights), broadcastable to (p, na, nb)."""
    _, na, nb = g.shape
    kk, ii, jj = at
    i1, i2 = g.ia[kk], g.ib[kk]
    d1v, d2v = rays.d1[at], rays.d2[at]
    z1, z2 = g.z_view[i1], g.z_view[i2]
    h1 = z1 + d1v * g.tan_top[i1, ii]
    h2 = z2 + d2v * g.tan_top[i2, jj]
    # Elsewhere (no distance) the height is the camera's own: constants of the pair and the cut flags.
    zc1, zc2 = g.z_view[g.ia][:, None, None], g.z_view[g.ib][:, None, None]
    hc1, hc2 = zc1, zc2
    cut1, cut2 = g.cut[g.ia, :na][:, :, None], g.cut[g.ib, :nb][:, None, :]
    if cut1.any() or cut2.any():
        # A head cut by the image's upper border is at least as high as it looks: consistent with any
        # taller height from the other view (both cut: no height evidence).
        c1v, c2v = cut1[kk, ii, 0], cut2[kk, 0, jj]
        h1, h2 = np.where(c1v, np.maximum(h1, h2), h1), np.where(c2v, np.maximum(h1, h2), h2)
        top = np.maximum(zc1, zc2)
        hc1, hc2 = np.where(cut1, top, zc1), np.where(cut2, top, zc2)
    r_hc_v = _log_ratio_score(h1, h2, params.height_sigma)
    r_hc = _log_ratio_score(hc1, hc2, params.height_sigma)
    if params.floor_sigma_m <= 0:
        return r_hc_v, r_hc
    # ... and the feet, where visible, must stand on the floor (z = 0) seen from both cameras.
    with np.errstate(invalid="ignore"):
        tan_bot = np.tan(g.per_blob[:, :, 3])
        s_view = g.tabs.views.sigma_rad[g.rows]
        g0 = 2.0 * params.floor_sigma_m**2
        for zs, dist, tb, sv in ((z1, d1v, tan_bot[i1, ii], s_view[i1]), (z2, d2v, tan_bot[i2, jj], s_view[i2])):
            zf = zs + dist * tb  # NaN where the feet are not visible: factor 1
            sig = params.floor_sigma_m + dist * sv * FEET_SIGMAS
            fin = np.isfinite(zf)
            r_hc_v = r_hc_v * np.where(fin, np.exp(-(np.where(fin, zf, 0.0) ** 2) / (2.0 * sig**2)), 1.0)
    # No distance: the feet are at the camera's height (where visible at all).
    feet1 = np.isfinite(tan_bot[g.ia, :na])[:, :, None]
    feet2 = np.isfinite(tan_bot[g.ib, :nb])[:, None, :]
    r_hc = r_hc * np.where(feet1, np.exp(-(zc1**2) / g0), 1.0)
    r_hc = r_hc * np.where(feet2, np.exp(-(zc2**2) / g0), 1.0)
    return r_hc_v, r_hc


def match_matrices(
    views: Views, pairs: Sequence[tuple[int, int]], params: MatchParams, blobs: Subset | None = None
) -> list[MatchMatrix]:
    """Eq. 7 for several camera pairs at once (one vectorised pass: with many cameras the largest tick stage).

    Each pair is (camera 1, camera 2) as positions in ``blobs.rows``, each view with only its blobs of ``blobs``
    (default: every blob of every view, positions then being view rows); row ``i`` of a result is the ``i``-th of
    camera 1's blobs there, column ``j`` the ``j``-th of camera 2's.

    Arrays carry a leading pair axis p and are padded to the largest blob counts; each result is a view of
    its pair's (na, nb) corner. See :func:`match_matrix` for the measures.

    Cost: the ray geometry (Eqs. 1-2) runs on every blob pair; the distance-dependent measures (ray
    convergence, widths, heights, feet) only on the pairs whose rays meet in range (in a room, most of
    them), their values elsewhere being constants of the views (0 distance).
    """
    if not pairs:
        return []
    g = _gather(views, blobs if blobs is not None else views.every(), pairs, params.floor_sigma_m > 0)
    rays = _rays(g, params)
    valid, use_sr, d1, d2 = rays.valid, rays.use_sr, rays.d1, rays.d2
    # -- the measures that depend on the distances: only where the rays meet in range ---------------------
    at = np.nonzero(valid)
    kk, ii, jj = at
    r_rc_v = _convergence(g, rays, at)
    # Width consistency: metric widths from both views (1 where Eq. 2 made them equal by construction).
    # A blob much wider than its partner is usually two people merged (occlusion), not a wrong match:
    # the width term never drops below ``width_floor``.
    width1 = 2.0 * d1[at] * g.tan_w[g.ia[kk], ii]
    width2 = 2.0 * d2[at] * g.tan_w[g.ib[kk], jj]
    r_wc_v = np.where(
        use_sr[at], 1.0, np.maximum(_log_ratio_score(width1, width2, params.width_sigma), params.width_floor)
    )
    r_hc_v, r_hc_elsewhere = _heights(g, rays, at, params)
    shape = g.shape
    r_rc = np.zeros(shape)
    r_rc[valid] = r_rc_v
    r_wc = np.where(use_sr, 1.0, max(0.0, params.width_floor))
    r_wc[valid] = r_wc_v
    r_hc = np.array(np.broadcast_to(r_hc_elsewhere, shape), dtype=np.float64)  # writable
    r_hc[valid] = r_hc_v
    r_all = np.zeros(shape)
    r_all[valid] = r_rc_v * r_wc_v * r_hc_v
    # -- colour ------------------------------------------------------------------------------------------------
    r_is = colour_table(params.use_colour, shape, tabs=g.tabs, ia=g.ia, ib=g.ib)
    hx = g.o1[:, 0, None, None] + d1 * np.cos(g.th1)  # (p, na, nb) hypothesised positions along camera 1's ray
    hy = g.o1[:, 1, None, None] + d1 * np.sin(g.th1)
    r = r_is * r_all
    xy = np.stack([hx, hy], axis=-1)
    sr_valid = use_sr & valid
    out: list[MatchMatrix] = []
    for k in range(len(pairs)):
        ka, kb = g.nas[k], g.nbs[k]
        parts = {
            "r_is": r_is[k, :ka, :kb],
            "r_rc": r_rc[k, :ka, :kb],
            "r_wc": r_wc[k, :ka, :kb],
            "r_hc": r_hc[k, :ka, :kb],
        }
        out.append(
            MatchMatrix(
                r=r[k, :ka, :kb],
                d1_m=d1[k, :ka, :kb],
                d2_m=d2[k, :ka, :kb],
                xy=xy[k, :ka, :kb],
                size_ratio=sr_valid[k, :ka, :kb],
                parts=parts,
            )
        )
    return out
