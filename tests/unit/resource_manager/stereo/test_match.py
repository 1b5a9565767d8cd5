"""Eq. (7) match measures (the matchers: test_matchers.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from resource_manager.stereo.match import MatchMatrix, MatchParams, get_matcher, match_matrix
from tests.unit.resource_manager.synth import ViewSpec, stack_views, view


def _match(a: ViewSpec, b: ViewSpec, params: MatchParams) -> MatchMatrix:
    """Eq. 7 of the blobs of ``a`` (camera 1) against those of ``b`` (camera 2)."""
    return match_matrix(stack_views([a, b]), 0, 1, params)


@pytest.mark.parametrize("matcher", ["greedy", "global"])
def test_fig6_two_against_three_blobs(matcher: str) -> None:
    """Fig. 6: 2 blobs in Pano 1, 3 in Pano 2; the correct matches are (T1¹, T2²) and (T2¹, T1²)."""
    people = {"A": (2.0, 3.0, 1.80, 1), "B": (4.5, 2.5, 1.65, 2), "C": (3.5, 5.0, 1.70, 3)}
    o1, o2 = (0.0, 0.0), (5.0, 0.0)
    # camera 1 sees A and B (C hidden); camera 2 sees B, A, C (in that blob order)
    v1 = view("p1", o1, [people["A"], people["B"]])
    v2 = view("p2", o2, [people["B"], people["A"], people["C"]])
    mm = _match(v1, v2, MatchParams())
    pairs = sorted(get_matcher(matcher).match(mm.r, 0.1))
    assert pairs == [(0, 1), (1, 0)]
    for i, j in pairs:
        target = [people["A"], people["B"]][i]
        assert np.hypot(*(mm.xy[i, j] - np.array(target[:2]))) < 1e-6


def test_measures_reject_diverging_and_inconsistent_pairs() -> None:
    v1 = view("p1", (0.0, 0.0), [(2.0, 2.0, 1.8, 1)])
    # camera 2 sees a person behind itself: the rays diverge
    v2 = view("p2", (4.0, 0.0), [(6.0, -2.0, 1.8, 1)])
    mm = _match(v1, v2, MatchParams())
    assert mm.parts["r_rc"][0, 0] == 0.0 and mm.r[0, 0] == 0.0
    # same direction but a child-height head in view 2: height consistency drops
    v3 = view("p3", (4.0, 0.0), [(2.0, 2.0, 1.0, 1)])
    assert _match(v1, v3, MatchParams()).parts["r_hc"][0, 0] < 0.1
    # different clothes: colour similarity drops
    v4 = view("p4", (4.0, 0.0), [(2.0, 2.0, 1.8, 7)])
    assert _match(v1, v4, MatchParams()).parts["r_is"][0, 0] < 0.5


def test_colinear_target_uses_size_ratio() -> None:
    """A target on the baseline between the cameras: Eq. 1 is singular, Eq. 2 localises it."""
    v1 = view("p1", (0.0, 0.0), [(3.0, 0.0, 1.8, 1)])
    v2 = view("p2", (5.0, 0.0), [(3.0, 0.0, 1.8, 1)])
    mm = _match(v1, v2, MatchParams())
    assert bool(mm.size_ratio[0, 0])
    assert mm.r[0, 0] > 0.5
    assert abs(mm.d1_m[0, 0] - 3.0) < 0.05


def test_batched_matrices_equal_single_ones() -> None:
    from resource_manager.stereo.match import match_matrices

    rng = np.random.default_rng(3)
    people = [(float(rng.uniform(0, 8)), float(rng.uniform(0, 6)), 1.7, k) for k in range(6)]
    views = [view(f"c{k}", o, people[: 2 + k]) for k, o in enumerate([(0.0, 0.0), (8.0, 0.0), (8.0, 6.0), (0.0, 6.0)])]
    views.append(view("e", (4.0, 3.0), []))
    pairs = [(0, 1), (2, 3), (1, 3), (0, 4)]
    batched = match_matrices(stack_views(views), pairs, MatchParams())
    for (i, j), mb in zip(pairs, batched, strict=True):
        a, b = views[i], views[j]
        single = _match(a, b, MatchParams())
        assert mb.r.shape == (a.n, b.n)
        assert np.allclose(mb.r, single.r) and np.allclose(mb.xy, single.xy)
        assert np.array_equal(mb.size_ratio, single.size_ratio)


def test_head_cut_by_the_image_top_is_only_a_lower_bound() -> None:
    import dataclasses

    # A person 0.9 m from camera a: the panorama (max elevation 20 deg) cuts the head at 20 deg, so the
    # apparent head top is 1.1 + 0.9 tan(20 deg) = 1.43 m for a 1.8 m person.
    person = (1.9, 0.0, 1.8, 0)
    a = view("a", (1.0, 0.0), [person])
    a = dataclasses.replace(a, top_elev_rad=np.array([math.radians(20.0)]))
    b = view("b", (1.9, 3.0), [person])
    p = MatchParams()
    refused = _match(a, b, p).r[0, 0]
    cut = dataclasses.replace(a, top_cut=np.array([True]))
    accepted = _match(cut, b, p).r[0, 0]
    assert refused < 0.2 < 0.5 < accepted  # 0.2: the default tau
    # ... but a lower bound still: a cut top above the other view's head is inconsistent.
    short = view("b", (1.9, 3.0), [(1.9, 0.0, 0.9, 0)])
    assert _match(cut, short, p).r[0, 0] < 0.2


# -- the vectorised Eq. 7 against a plain dense evaluation --------------------------------------------------


def _dense_reference(a: ViewSpec, b: ViewSpec, p: MatchParams) -> dict[str, np.ndarray]:
    """Eq. 7 of one pair, every measure on every blob pair (the implementation before the batched one)."""
    from scipy.special import ndtr

    from common.errors import GeometryError
    from common.geometry import size_ratio, triangulate

    def lrs(v1: np.ndarray, v2: np.ndarray, s: float) -> np.ndarray:
        ok = (v1 > 0) & (v2 > 0)
        with np.errstate(divide="ignore", invalid="ignore"):
            lr = np.where(ok, np.log(np.where(ok, v1, 1.0) / np.where(ok, v2, 1.0)), 0.0)
        return np.where(ok, np.exp(-(lr**2) / (2.0 * s**2)), 0.0)

    def wrap(x: np.ndarray) -> np.ndarray:
        return (x + math.pi) % (2 * math.pi) - math.pi

    d = b.origin_xy - a.origin_xy
    base, psi = math.hypot(*d), math.atan2(d[1], d[0])
    sigma = max(math.hypot(a.sigma_rad, b.sigma_rad) / math.sqrt(2.0), 1e-6)
    a1, a2 = wrap(a.bearing_rad[:, None] - psi), wrap(psi + math.pi - b.bearing_rad[None, :])
    abs1, abs2 = np.abs(a1), np.abs(a2)
    same = np.sign(a1) == np.sign(a2)
    conv = same & (abs1 + abs2 < math.pi)
    phi0 = math.pi - abs1 - abs2
    margin = np.where(conv, np.minimum(np.minimum(abs1, abs2), phi0), np.where(same, phi0, -np.minimum(abs1, abs2)))
    r_conv = ndtr(margin / (math.sqrt(2.0) * sigma))
    col_d = np.minimum(
        np.maximum(abs1, abs2), np.minimum(np.maximum(abs1, math.pi - abs2), np.maximum(math.pi - abs1, abs2))
    )
    r_col = np.exp(-(col_d**2) / (4.0 * sigma**2))
    with np.errstate(divide="ignore", invalid="ignore"):
        d1_t, d2_t = triangulate(base, abs1, abs2)
    w1, w2 = np.broadcast_arrays(a.width_rad[:, None], b.width_rad[None, :])
    use_sr = col_d < np.maximum(p.colinear_sigmas * sigma, 0.5 * np.minimum(w1, w2))
    d1_s, d2_s = np.full(use_sr.shape, np.nan), np.full(use_sr.shape, np.nan)
    for i, j in np.argwhere(use_sr):
        c1, c2 = (1.0 if abs1[i, 0] < math.pi / 2 else -1.0), (1.0 if abs2[0, j] < math.pi / 2 else -1.0)
        try:
            d1_s[i, j], d2_s[i, j] = size_ratio(base, math.sin(w1[i, j] / 2), math.sin(w2[i, j] / 2), c1, c2)
        except GeometryError:
            use_sr[i, j] = False
    d1 = np.where(use_sr, d1_s, np.where(conv, d1_t, np.nan))
    d2 = np.where(use_sr, d2_s, np.where(conv, d2_t, np.nan))
    with np.errstate(invalid="ignore"):
        valid = np.isfinite(d1) & np.isfinite(d2) & (d1 > 0) & (d2 > 0) & (d1 <= p.max_range_m) & (d2 <= p.max_range_m)
    d1, d2 = np.where(valid, d1, 0.0), np.where(valid, d2, 0.0)
    r_rc = np.where(valid, np.where(use_sr, np.maximum(r_conv, r_col), r_conv), 0.0)
    lw = lrs(2.0 * d1 * np.tan(w1 / 2.0), 2.0 * d2 * np.tan(w2 / 2.0), p.width_sigma)
    r_wc = np.where(use_sr, 1.0, np.maximum(lw, p.width_floor))
    h1 = a.z_m + d1 * np.tan(a.top_elev_rad[:, None])
    h2 = b.z_m + d2 * np.tan(b.top_elev_rad[None, :])
    cut1 = np.zeros((a.n, 1), bool) if a.top_cut is None else a.top_cut[:, None]
    cut2 = np.zeros((1, b.n), bool) if b.top_cut is None else b.top_cut[None, :]
    h1, h2 = np.where(cut1, np.maximum(h1, h2), h1), np.where(cut2, np.maximum(h1, h2), h2)
    r_hc = lrs(h1, h2, p.height_sigma)
    if p.floor_sigma_m > 0:
        for v, dist, bottom in ((a, d1, "row"), (b, d2, "col")):
            bot = np.full(v.n, np.nan) if v.bottom_elev_rad is None else v.bottom_elev_rad
            bot = bot[:, None] if bottom == "row" else bot[None, :]
            with np.errstate(invalid="ignore"):
                zf = v.z_m + dist * np.tan(bot)
            sig = p.floor_sigma_m + dist * v.sigma_rad * 4.0
            r_hc = r_hc * np.where(np.isfinite(zf), np.exp(-(np.nan_to_num(zf) ** 2) / (2.0 * sig**2)), 1.0)
    if p.use_colour and a.hist is not None and b.hist is not None and a.hist.shape[1] == b.hist.shape[1]:
        r_is = np.clip(np.sqrt(a.hist) @ np.sqrt(b.hist).T, 0.0, 1.0)
    else:
        r_is = np.ones((a.n, b.n))
    r0 = r_is * r_rc * r_wc * r_hc
    xy = np.stack(
        [a.origin_xy[0] + d1 * np.cos(a.bearing_rad[:, None]), a.origin_xy[1] + d1 * np.sin(a.bearing_rad[:, None])], -1
    )
    return {"r": r0, "d1": d1, "d2": d2, "xy": xy, "sr": use_sr & valid, "r_is": r_is, "r_rc": r_rc,
            "r_wc": r_wc, "r_hc": r_hc}  # fmt: skip


def _random_view(rng: np.random.Generator, sid: str, origin: tuple[float, float], people: np.ndarray) -> ViewSpec:
    """A camera seeing a random subset of ``people`` (x, y, height) with noise, cut heads, hidden feet, colours."""
    import dataclasses

    sel = people[rng.random(len(people)) < 0.8]
    v = view(sid, origin, [(float(x), float(y), float(h), int(k)) for k, (x, y, h) in enumerate(sel)])
    n = v.n
    bottom = np.arctan2(-v.z_m, np.maximum(np.hypot(*(sel[:, :2] - v.origin_xy).T), 0.1)) if n else np.zeros(0)
    bottom = np.where(rng.random(n) < 0.3, np.nan, bottom + rng.normal(0, 0.01, n))
    return dataclasses.replace(
        v,
        bearing_rad=v.bearing_rad + rng.normal(0, 0.004, n),
        width_rad=v.width_rad * rng.uniform(0.7, 1.4, n),
        top_elev_rad=v.top_elev_rad + rng.normal(0, 0.01, n),
        bottom_elev_rad=bottom,
        top_cut=rng.random(n) < 0.15,
        sigma_rad=float(rng.uniform(0.002, 0.01)),
        z_m=float(rng.uniform(0.8, 1.4)),
        hist=v.hist if sid != "nohist" else None,
    )


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_batched_eq7_equals_dense_reference(seed: int) -> None:
    """The batched, gated Eq. 7 gives the dense evaluation's values on every blob pair of every pair.

    Cameras on one line (colinear targets: Eq. 2), targets out of range, cut heads, hidden feet, a view
    without histograms.
    """
    from resource_manager.stereo.match import match_matrices

    rng = np.random.default_rng(seed)
    people = np.column_stack([rng.uniform(-2, 10, 12), rng.uniform(-1, 7, 12), rng.uniform(1.5, 1.9, 12)])
    people[:3, 1] = 0.0  # on the x axis: colinear with cameras c0, c1 and c4
    people[3] = (40.0, 3.0, 1.7)  # out of range
    origins = [(0.0, 0.0), (8.0, 0.0), (8.0, 6.0), (0.0, 6.0), (4.0, 0.0), (4.0, 6.5)]
    views = [_random_view(rng, f"c{k}", o, people) for k, o in enumerate(origins)]
    views.append(_random_view(rng, "nohist", (-1.0, 3.0), people))
    params = MatchParams(max_range_m=25.0, floor_sigma_m=0.25, width_floor=0.1)
    for with_hist in (True, False):
        pool = views if not with_hist else views[:-1]
        pairs = [(i, j) for i in range(len(pool)) for j in range(len(pool)) if i != j]
        got = match_matrices(stack_views(pool), pairs, params)
        for (i, j), mm in zip(pairs, got, strict=True):
            a, b = pool[i], pool[j]
            ref = _dense_reference(a, b, params)
            assert mm.r.shape == (a.n, b.n)
            np.testing.assert_allclose(mm.r, ref["r"], rtol=1e-12, atol=1e-15)
            for name, key in (("d1_m", "d1"), ("d2_m", "d2"), ("xy", "xy")):
                np.testing.assert_allclose(getattr(mm, name), ref[key], rtol=1e-12, atol=1e-12)
            assert np.array_equal(mm.size_ratio, ref["sr"])
            for part in ("r_is", "r_rc", "r_wc", "r_hc"):
                np.testing.assert_allclose(mm.parts[part], ref[part], rtol=1e-12, atol=1e-15)
        assert any(mm.size_ratio.any() for mm in got)  # the colinear branch was exercised
        assert any((mm.r > 0.2).any() for mm in got)
