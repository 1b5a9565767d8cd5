"""3D blob-based stereo match (paper, "3D Blob-Based Stereo Match", Eq. 7).

For two cameras with known poses, every blob i of camera a is scored against
every blob j of camera b::

    r(i, j) = r_is(i, j) · r_rc(i, j) · r_wc(i, j) · r_hc(i, j)      (Eq. 7)

* r_is: colour similarity, the Bhattacharyya coefficient of the histograms;
* r_rc: ray convergence; soft, from the smallest inner angle of the triangle
  O1-O2-T against the bearing error, with a colinear branch where the
  size-ratio method (Eq. 2) takes over (notes/geometry.md §4);
* r_wc: width consistency of the metric widths W_k = 2 D_k tan(w_k / 2);
* r_hc: height consistency of the head-top heights H_k = z_k + D_k tan(top_k).

A temporal consistency term from the current tracks is added:
``r' = (r + λ c_t) / (1 + λ)`` with c_t = 1 when both blobs already support
the same track (only where r alone already exceeds the threshold). Two matchers turn the
matrix into pairs, chosen by name (STYLE.md habit 12): ``greedy`` (the
paper's, O(N³/3)) and ``global`` (Hungarian on the sum of confidences, with a
private "unmatched" dummy per row and column).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Final, Protocol

import numpy as np
import numpy.typing as npt
from scipy.optimize import linear_sum_assignment
from scipy.special import ndtr

from common.errors import GeometryError
from common.geometry import size_ratio, triangulate

__all__ = [
    "MATCHERS",
    "GlobalMatcher",
    "GreedyMatcher",
    "MatchMatrix",
    "MatchParams",
    "Matcher",
    "ViewBlobs",
    "get_matcher",
    "match_matrices",
    "match_matrix",
]

FloatArray = npt.NDArray[np.float64]
TWO_PI: Final = 2.0 * math.pi


@dataclass(frozen=True, slots=True)
class ViewBlobs:
    """The blobs of one camera at the fusion instant, in world terms."""

    sensor_id: str
    origin_xy: FloatArray
    """(2,) optical centre on the floor plane."""
    z_m: float
    """Height of the optical centre."""
    sigma_rad: float
    """1-sigma bearing error (the sensor's, plus its pose's yaw error)."""
    bearing_rad: FloatArray
    """(n,) world azimuths of the heads."""
    width_rad: FloatArray
    """(n,) angular widths."""
    top_elev_rad: FloatArray
    """(n,) elevations of the blob tops."""
    hist: FloatArray | None
    """(n, k) L1-normalised histograms, or None when the sensor sends none."""
    local_id: npt.NDArray[np.int64]
    """(n,) the node's 2D track ids."""
    hist_sqrt: FloatArray | None = None
    """Element-wise square roots of ``hist`` (for the Bhattacharyya coefficient), precomputed per view."""
    bottom_elev_rad: FloatArray | None = None
    """(n,) elevations of the blob bottoms (feet), NaN where the feet are not visible; None: unknown."""
    fov: tuple[float, float] | None = None
    """(world azimuth of the optical axis, half width) of a perspective camera; None: 360 deg (panoramic)."""
    mono_range_m: FloatArray | None = None
    """(n,) floor distance of each blob from its feet elevation (:mod:`~resource_manager.mono`), NaN where
    not observable; None: the camera gives none."""
    mono_sigma_m: FloatArray | None = None
    """(n,) 1-sigma of ``mono_range_m``."""
    top_cut: npt.NDArray[np.bool_] | None = None
    """(n,) blobs whose top touches the image's upper border (a person close to the camera): their head-top
    height is only a lower bound. None: none are."""

    def sees(self, azimuth_rad: float) -> bool:
        """Whether a world azimuth is inside this camera's horizontal field of view."""
        if self.fov is None:
            return True
        return abs(math.remainder(azimuth_rad - self.fov[0], 2 * math.pi)) <= self.fov[1]

    @property
    def n(self) -> int:
        return int(self.bearing_rad.shape[0])


@dataclass(frozen=True, slots=True)
class MatchParams:
    """The knobs of Eq. 7 (see ``[match]`` in the config)."""

    max_range_m: float = 30.0
    width_sigma: float = 0.35
    height_sigma: float = 0.12
    use_colour: bool = True
    temporal_weight: float = 1.0
    floor_sigma_m: float = 0.0
    """Spread of the feet height z_cam + D tan(bottom) around the floor (0: not used)."""
    width_floor: float = 0.0
    """Smallest r_wc (merged blobs of occluding people are wide; 0: strict)."""
    temporal_gate_m: float = 0.6
    """Distance of a hypothesis from a track's prediction at which the positional temporal term is exp(-1/2)."""
    colinear_sigmas: float = 2.0
    """A target within this many bearing sigmas (or its own half width) of the baseline is size-ratio."""


@dataclass(frozen=True, slots=True)
class MatchMatrix:
    """Eq. 7 for every blob pair of two views, and the hypothesised targets."""

    r: FloatArray
    """(na, nb) total confidence (with the temporal term when given)."""
    d1_m: FloatArray
    d2_m: FloatArray
    xy: FloatArray
    """(na, nb, 2) hypothesised target positions."""
    size_ratio: npt.NDArray[np.bool_]
    """(na, nb) True where Eq. 2 (size-ratio) was used instead of Eq. 1."""
    parts: dict[str, FloatArray]
    """The factors r_is, r_rc, r_wc, r_hc, c_t (for tests and diagnostics)."""


def _wrap(a: FloatArray) -> FloatArray:
    return np.asarray((a + math.pi) % TWO_PI - math.pi, dtype=np.float64)


def _log_ratio_score(v1: FloatArray, v2: FloatArray, sigma: float) -> FloatArray:
    """exp(-ln²(v1/v2) / 2σ²); 0 where either value is not positive."""
    ok = (v1 > 0) & (v2 > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        lr = np.where(ok, np.log(np.where(ok, v1, 1.0) / np.where(ok, v2, 1.0)), 0.0)
    return np.where(ok, np.exp(-(lr**2) / (2.0 * sigma**2)), 0.0)


def match_matrix(
    a: ViewBlobs, b: ViewBlobs, params: MatchParams, temporal: FloatArray | None = None, threshold: float = 0.1
) -> MatchMatrix:
    """Score every blob of ``a`` against every blob of ``b`` (Eq. 7).

    Args:
        a: camera 1 (O1).
        b: camera 2 (O2).
        params: measure settings.
        temporal: (na, nb) c_t in [0, 1] from the current tracks, or None.
        threshold: tau; the temporal term is added only where r itself exceeds it.
    """
    return match_matrices([(a, b)], params, [temporal], threshold)[0]


def _pad(rows: list[FloatArray], n: int, fill: float = np.nan) -> FloatArray:
    out = np.full((len(rows), max(n, 1)), fill)
    for k, r in enumerate(rows):
        out[k, : r.shape[0]] = r
    return out


def _pad_bool(arrays: Sequence[npt.NDArray[np.bool_] | None], counts: Sequence[int], n: int) -> npt.NDArray[np.bool_]:
    """(k, n) flags, False where an array is None or beyond its length."""
    out = np.zeros((len(arrays), max(n, 1)), dtype=bool)
    for k, (arr, c) in enumerate(zip(arrays, counts, strict=True)):
        if arr is not None and c:
            out[k, :c] = arr[:c]
    return out


def match_matrices(
    pairs: list[tuple[ViewBlobs, ViewBlobs]],
    params: MatchParams,
    temporals: Sequence[FloatArray | None] | None = None,
    threshold: float = 0.1,
    track_xy: FloatArray | None = None,
) -> list[MatchMatrix]:
    """Eq. 7 for several camera pairs at once (one vectorised pass; with many cameras this is most of a tick).

    Arrays carry a leading pair axis p and are padded to the largest blob counts; each result is sliced back
    to its pair's (na, nb). See :func:`match_matrix` for the measures. ``track_xy`` (m, 2): the tracks'
    predicted positions; a hypothesis near one gets the temporal term c_t = exp(-d²/2g²) even when the
    nodes' 2D ids changed (the link-based c_t of ``temporals`` needs them unchanged).
    """
    if not pairs:
        return []
    temporals = list(temporals) if temporals is not None else [None] * len(pairs)
    nas = [a.n for a, _ in pairs]
    nbs = [b.n for _, b in pairs]
    na, nb = max(*nas, 1), max(*nbs, 1)
    o1 = np.array([a.origin_xy for a, _ in pairs])
    o2 = np.array([b.origin_xy for _, b in pairs])
    d = o2 - o1
    base = np.hypot(d[:, 0], d[:, 1])[:, None, None]
    psi12 = np.arctan2(d[:, 1], d[:, 0])[:, None, None]
    sigma = np.maximum(np.array([math.hypot(a.sigma_rad, b.sigma_rad) / math.sqrt(2.0) for a, b in pairs]), 1e-6)[
        :, None, None
    ]
    th1 = _pad([a.bearing_rad for a, _ in pairs], na)[:, :, None]
    th2 = _pad([b.bearing_rad for _, b in pairs], nb)[:, None, :]
    # Signed inner angles at O1 and O2 (notes/geometry.md §4).
    a1 = _wrap(th1 - psi12)  # (p, na, 1)
    a2 = _wrap(psi12 + math.pi - th2)  # (p, 1, nb)
    abs1, abs2 = np.abs(a1), np.abs(a2)
    same_side = np.sign(a1) == np.sign(a2)  # (p, na, nb) from here on
    converge = same_side & (abs1 + abs2 < math.pi)
    phi0 = math.pi - abs1 - abs2
    margin = np.where(
        converge, np.minimum(np.minimum(abs1, abs2), phi0), np.where(same_side, phi0, -np.minimum(abs1, abs2))
    )
    r_conv = ndtr(margin / (math.sqrt(2.0) * sigma))
    col_d = np.minimum(
        np.maximum(abs1, abs2), np.minimum(np.maximum(abs1, math.pi - abs2), np.maximum(math.pi - abs1, abs2))
    )
    r_col = np.exp(-(col_d**2) / (4.0 * sigma**2))
    # Eq. 1 (triangulation) where the triangle is proper.
    with np.errstate(divide="ignore", invalid="ignore"):
        d1_t, d2_t = triangulate(base, abs1, abs2)
    shape = (len(pairs), na, nb)
    d1_t = np.broadcast_to(np.asarray(d1_t, dtype=np.float64), shape)
    d2_t = np.broadcast_to(np.asarray(d2_t, dtype=np.float64), shape)
    # Eq. 2 (size-ratio) where target and baseline are (nearly) colinear: the crossover of
    # notes/geometry.md §3, phi1 < w1·dphi/dw, taken here as "the target's image covers the epipole".
    w1 = np.broadcast_to(_pad([a.width_rad for a, _ in pairs], na)[:, :, None], shape)
    w2 = np.broadcast_to(_pad([b.width_rad for _, b in pairs], nb)[:, None, :], shape)
    with np.errstate(invalid="ignore"):
        colinear_gap = np.maximum(params.colinear_sigmas * sigma, 0.5 * np.minimum(w1, w2))
        use_sr = col_d < colinear_gap
    d1_s = np.full(shape, np.nan)
    d2_s = np.full(shape, np.nan)
    for k, i, j in np.argwhere(use_sr):
        c1 = 1.0 if abs1[k, i, 0] < math.pi / 2 else -1.0
        c2 = 1.0 if abs2[k, 0, j] < math.pi / 2 else -1.0
        try:  # Eq. 2 with sizes sin(w/2) (exact for a cylinder of the target's width)
            d1_s[k, i, j], d2_s[k, i, j] = size_ratio(
                float(base[k, 0, 0]), math.sin(w1[k, i, j] / 2), math.sin(w2[k, i, j] / 2), c1, c2
            )
        except GeometryError:
            use_sr[k, i, j] = False
    d1 = np.where(use_sr, d1_s, np.where(converge, d1_t, np.nan))
    d2 = np.where(use_sr, d2_s, np.where(converge, d2_t, np.nan))
    with np.errstate(invalid="ignore"):
        valid = np.isfinite(d1) & np.isfinite(d2) & (d1 > 0) & (d2 > 0)
        valid &= (d1 <= params.max_range_m) & (d2 <= params.max_range_m)
    d1 = np.where(valid, d1, 0.0)
    d2 = np.where(valid, d2, 0.0)
    r_rc = np.where(valid, np.where(use_sr, np.maximum(r_conv, r_col), r_conv), 0.0)
    # Width consistency: metric widths from both views (1 where Eq. 2 made them equal by construction).
    width1 = 2.0 * d1 * np.tan(np.nan_to_num(w1) / 2.0)
    width2 = 2.0 * d2 * np.tan(np.nan_to_num(w2) / 2.0)
    # A blob much wider than its partner is usually two people merged (occlusion), not a wrong match:
    # the width term never drops below ``width_floor``.
    r_wc = np.where(use_sr, 1.0, np.maximum(_log_ratio_score(width1, width2, params.width_sigma), params.width_floor))
    # Height consistency: head-top height from each view.
    z1 = np.array([a.z_m for a, _ in pairs])[:, None, None]
    z2 = np.array([b.z_m for _, b in pairs])[:, None, None]
    top1 = np.nan_to_num(_pad([a.top_elev_rad for a, _ in pairs], na))[:, :, None]
    top2 = np.nan_to_num(_pad([b.top_elev_rad for _, b in pairs], nb))[:, None, :]
    h1 = z1 + d1 * np.tan(top1)
    h2 = z2 + d2 * np.tan(top2)
    cut1 = _pad_bool([a.top_cut for a, _ in pairs], [a.n for a, _ in pairs], na)[:, :, None]
    cut2 = _pad_bool([b.top_cut for _, b in pairs], [b.n for _, b in pairs], nb)[:, None, :]
    if cut1.any() or cut2.any():
        # A head cut by the image's upper border is at least as high as it looks: consistent with any
        # taller height from the other view (both cut: no height evidence).
        h1, h2 = np.where(cut1, np.maximum(h1, h2), h1), np.where(cut2, np.maximum(h1, h2), h2)
    r_hc = _log_ratio_score(h1, h2, params.height_sigma)
    # ... and the feet, where visible, must stand on the floor (z = 0) seen from both cameras.
    if params.floor_sigma_m > 0:
        nan = np.full(0, np.nan)
        bot1 = _pad([a.bottom_elev_rad if a.bottom_elev_rad is not None else nan for a, _ in pairs], na)
        bot2 = _pad([b.bottom_elev_rad if b.bottom_elev_rad is not None else nan for _, b in pairs], nb)
        s1 = np.array([a.sigma_rad for a, _ in pairs])[:, None, None]
        s2 = np.array([b.sigma_rad for _, b in pairs])[:, None, None]
        for z, dist, bottom, sv in ((z1, d1, bot1[:, :, None], s1), (z2, d2, bot2[:, None, :], s2)):
            with np.errstate(invalid="ignore"):
                zf = z + dist * np.tan(bottom)
            sig = params.floor_sigma_m + dist * sv * 4.0
            r_hc = r_hc * np.where(np.isfinite(zf), np.exp(-(np.nan_to_num(zf) ** 2) / (2.0 * sig**2)), 1.0)
    r_all = r_rc * r_wc * r_hc
    lam = params.temporal_weight
    out: list[MatchMatrix] = []
    cos1, sin1 = np.cos(th1), np.sin(th1)
    c_pos = None
    if track_xy is not None and track_xy.size and lam > 0 and params.temporal_gate_m > 0:
        hx = o1[:, 0, None, None] + d1 * cos1  # (p, na, nb)
        hy = o1[:, 1, None, None] + d1 * sin1
        tx, ty = track_xy[:, 0], track_xy[:, 1]
        d2min = np.min((hx[..., None] - tx) ** 2 + (hy[..., None] - ty) ** 2, axis=-1)
        c_pos = np.where(valid, np.exp(-d2min / (2.0 * params.temporal_gate_m**2)), 0.0)
    for k, ((a, b), temporal) in enumerate(zip(pairs, temporals, strict=True)):
        ka, kb = nas[k], nbs[k]
        # Intensity similarity: Bhattacharyya coefficient of the colour histograms.
        if params.use_colour and a.hist is not None and b.hist is not None and a.hist.shape[1] == b.hist.shape[1]:
            sa = a.hist_sqrt if a.hist_sqrt is not None else np.sqrt(np.clip(a.hist, 0.0, None))
            sb = b.hist_sqrt if b.hist_sqrt is not None else np.sqrt(np.clip(b.hist, 0.0, None))
            r_is = np.clip(sa @ sb.T, 0.0, 1.0)
        else:
            r_is = np.ones((ka, kb))
        r = r_is * r_all[k, :ka, :kb]
        c_t = np.zeros((ka, kb)) if temporal is None else np.asarray(temporal, dtype=np.float64)
        if c_pos is not None:
            c_t = np.maximum(c_t, c_pos[k, :ka, :kb])
        if (temporal is not None or c_pos is not None) and lam > 0:
            # The temporal term can lift a plausible pair, never rescue one that Eq. 7 itself rejects.
            r = (r + lam * c_t * (r > threshold)) / (1.0 + lam)
        dk = d1[k, :ka, :kb]
        # Hypothesised positions along camera 1's ray.
        xy = np.empty((ka, kb, 2))
        xy[..., 0] = o1[k, 0] + dk * cos1[k, :ka]
        xy[..., 1] = o1[k, 1] + dk * sin1[k, :ka]
        parts = {
            "r_is": r_is,
            "r_rc": r_rc[k, :ka, :kb],
            "r_wc": r_wc[k, :ka, :kb],
            "r_hc": r_hc[k, :ka, :kb],
            "c_t": c_t,
        }
        out.append(
            MatchMatrix(
                r=r,
                d1_m=dk,
                d2_m=d2[k, :ka, :kb],
                xy=xy,
                size_ratio=(use_sr & valid)[k, :ka, :kb],
                parts=parts,
            )
        )
    return out


class Matcher(Protocol):
    """Turns a confidence matrix into one-to-one pairs above a threshold."""

    name: str

    def match(self, r: FloatArray, threshold: float) -> list[tuple[int, int]]:
        """Return (row, column) pairs, each row and column at most once, every r > threshold."""
        ...


class GreedyMatcher:
    """The paper's greedy matcher: take the largest entry, delete its row and column, repeat.

    Scanning the remaining (N-k)x(N-k) matrix N times costs Σ m² ≈ N³/3 comparisons.
    """

    name = "greedy"

    def match(self, r: FloatArray, threshold: float) -> list[tuple[int, int]]:
        m = np.array(r, dtype=np.float64, copy=True)
        out: list[tuple[int, int]] = []
        if m.size == 0:
            return out
        for _ in range(min(m.shape)):
            flat = int(np.argmax(m))
            i, j = divmod(flat, m.shape[1])
            if not m[i, j] > threshold:
                break
            out.append((i, j))
            m[i, :] = -np.inf
            m[:, j] = -np.inf
        return out


class GlobalMatcher:
    """Maximise the total confidence (Hungarian), each blob free to stay unmatched.

    The (na+nb) square problem gives every row and column a private dummy worth
    threshold/2, so a real pair is taken only when r > threshold (notes/geometry.md §4).
    """

    name = "global"

    def match(self, r: FloatArray, threshold: float) -> list[tuple[int, int]]:
        na, nb = r.shape
        if na == 0 or nb == 0:
            return []
        forbid = -1e6
        n = na + nb
        w = np.full((n, n), forbid)
        w[:na, :nb] = np.where(r > threshold, r, forbid)
        u = threshold / 2.0
        w[np.arange(na), nb + np.arange(na)] = u
        w[na + np.arange(nb), np.arange(nb)] = u
        w[na:, nb:] = 0.0
        rows, cols = linear_sum_assignment(w, maximize=True)
        return [(int(i), int(j)) for i, j in zip(rows, cols, strict=True) if i < na and j < nb and r[i, j] > threshold]


MATCHERS: Final[dict[str, type[GreedyMatcher] | type[GlobalMatcher]]] = {
    GreedyMatcher.name: GreedyMatcher,
    GlobalMatcher.name: GlobalMatcher,
}
"""Matchers by the name used in ``[manager] matcher``."""


def get_matcher(name: str) -> Matcher:
    """Instantiate a matcher by registry name (KeyError names the choices)."""
    try:
        return MATCHERS[name]()
    except KeyError as err:
        raise KeyError(f"unknown matcher {name!r}; choose from {sorted(MATCHERS)}") from err
