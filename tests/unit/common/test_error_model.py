"""Model M1 (docs/geometry.md section 2), Fig. 4, Eqs. (4)-(6) and the pair ranking error."""

from __future__ import annotations

import math

import numpy as np
import pytest

from common.angles import wrap_angle
from common.error_model import (
    MAX_ERROR_M,
    eq5_bound,
    eq6_fixed_baseline,
    error_map,
    m1_error,
    normalised_error_xy,
    optimal_configuration,
    optimal_positions_world,
    pair_error_f,
    pair_position_error,
    pair_position_errors,
)
from common.geometry import baseline_exact, triangulate

R = 0.18
D1 = 6.0
OPT = optimal_configuration(D1, R)


def test_fig4_optimum_under_m1() -> None:
    """notes section 2.3: B* = 2.1655 +- 0.005 m, phi1* = 59.45 +- 0.1 deg, E* = 11.098 +- 0.02."""
    assert OPT.baseline_m == pytest.approx(2.1655, abs=0.005)
    assert math.degrees(OPT.phi1_rad) == pytest.approx(59.45, abs=0.1)
    assert OPT.normalised_error == pytest.approx(11.098, abs=0.02)
    # The acceptance window of notes section 2.4.
    assert 2.05 <= OPT.baseline_m <= 2.30 and 55 <= math.degrees(OPT.phi1_rad) <= 64


def test_fig4_optimum_with_exact_baseline_derivative() -> None:
    cfg = optimal_configuration(D1, R, exact_baseline=True)
    assert cfg.baseline_m == pytest.approx(2.1614, abs=0.005)
    assert math.degrees(cfg.phi1_rad) == pytest.approx(59.507, abs=0.1)
    assert cfg.normalised_error == pytest.approx(11.0775, abs=0.02)


def test_two_symmetric_optima() -> None:
    (xa, ya), (xb, yb) = OPT.o2_xy_pair
    assert (xa, ya) == (pytest.approx(1.1007, abs=0.005), pytest.approx(1.8649, abs=0.005))
    assert xa == xb and ya == -yb
    assert normalised_error_xy(xa, ya, D1, R) == pytest.approx(normalised_error_xy(xb, yb, D1, R), rel=1e-15)
    # Both are local minima of the map: every neighbour is worse.
    for x, y in OPT.o2_xy_pair:
        ang = np.linspace(0, 2 * np.pi, 16, endpoint=False)
        ring = normalised_error_xy(x + 0.01 * np.cos(ang), y + 0.01 * np.sin(ang), D1, R)
        assert np.all(ring > OPT.normalised_error)


def test_papers_point_within_0_2_percent() -> None:
    """The paper's (B = 2.2 m, phi1 = 62.1 deg) lies within 0.2 % of the M1 minimum (notes: +0.100 %)."""
    phi = math.radians(62.1)
    e = normalised_error_xy(2.2 * math.cos(phi), 2.2 * math.sin(phi), D1, R)
    assert e == pytest.approx(11.1095, abs=0.001)
    assert OPT.normalised_error <= e <= 1.002 * OPT.normalised_error


@pytest.mark.parametrize(
    ("d1", "b_star", "phi1_deg", "err_per_rad"),
    # notes section 2.2 table (R = 0.18 m)
    [(2, 1.4407, 30.91, 11.60), (3, 1.6139, 45.18, 22.50), (4, 1.8115, 51.97, 35.47), (6, 2.1655, 59.451, 66.590),
     (8, 2.4731, 63.73, 103.59), (10, 2.7476, 66.60, 145.65)],
)  # fmt: skip
def test_eq4_conclusion1_table(d1: float, b_star: float, phi1_deg: float, err_per_rad: float) -> None:
    cfg = optimal_configuration(d1, R)
    assert cfg.baseline_m == pytest.approx(b_star, abs=0.002)
    assert math.degrees(cfg.phi1_rad) == pytest.approx(phi1_deg, abs=0.05)
    assert cfg.normalised_error * d1 == pytest.approx(err_per_rad, abs=0.02)
    # Eq. (4), second half, holds exactly at the optimum; first half is its asymptote B ~ 2 sqrt(D1 R).
    b = cfg.baseline_m
    assert math.cos(cfg.phi1_rad) == pytest.approx(3 * b * d1 / (2 * d1 * d1 + b * b), abs=1e-6)
    assert 1.0 < b / (2 * math.sqrt(d1 * R)) < 1.21
    # Eq. (5): the optimum's error stays below 2 D1 sqrt(D1/R) dphi.
    assert cfg.normalised_error * d1 < eq5_bound(d1, R, 1.0)


def test_eq5_value_and_ratio() -> None:
    assert eq5_bound(6.0, 0.18, 1.0) == pytest.approx(69.282, abs=0.001)
    assert eq5_bound(6.0, 0.18, math.radians(0.2)) == pytest.approx(69.282 * math.radians(0.2), rel=1e-4)
    assert OPT.normalised_error * D1 / eq5_bound(D1, R, 1.0) == pytest.approx(0.961, abs=0.001)


@pytest.mark.parametrize("d1", [2.0, 4.0, 6.0, 10.0])
def test_eq6_fixed_baseline(d1: float) -> None:
    """Eq. (6): best case of a B = 2R head without calibration error ~ D1^2/R dphi (notes: 33.258 D1 at 6 m)."""
    e6 = eq6_fixed_baseline(d1, R, 1.0)
    # Eq. (6) is the leading term: the exact value is D1^2/R (1 - ~2.5 R^2/D1^2).
    assert e6 == pytest.approx(d1 * d1 / R, rel=3 * R * R / (d1 * d1))
    assert e6 < d1 * d1 / R
    # It is the minimum of M1 (baseline known) over camera 2 on the circle of radius 2R around O1.
    phis = np.linspace(0.01, math.pi - 0.01, 20001)
    o2 = np.column_stack([2 * R * np.cos(phis), 2 * R * np.sin(phis)])
    errs = [m1_error((0.0, 0.0), p, (d1, 0.0), R, 1.0, baseline_known=True) for p in o2[::20]]
    assert min(errs) == pytest.approx(e6, rel=1e-3) and min(errs) >= e6 * (1 - 1e-9)
    # Conclusion 2: adaptive (Eq. 5 regime) beats the fixed head.
    assert optimal_configuration(d1, R).normalised_error * d1 < e6
    if d1 == 6.0:
        assert e6 / d1 == pytest.approx(33.258, abs=0.001)


def test_m1_general_positions_match_the_cartesian_form() -> None:
    """Model M1 for arbitrary poses equals Fig. 4's normalised form after a rigid motion."""
    rng = np.random.default_rng(0)
    for _ in range(20):
        x, y = rng.uniform(-3, 8), rng.uniform(0.2, 4) * rng.choice([-1, 1])
        ang, shift = rng.uniform(-np.pi, np.pi), rng.uniform(-5, 5, 2)
        rot = np.array([[math.cos(ang), -math.sin(ang)], [math.sin(ang), math.cos(ang)]])
        o1, o2, t = shift, shift + rot @ [x, y], shift + rot @ [D1, 0.0]
        dphi = 0.0035
        assert m1_error(o1, o2, t, R, dphi, baseline_known=False) == pytest.approx(
            normalised_error_xy(x, y, D1, R) * D1 * dphi, rel=1e-10
        )
        # Known poses: the baseline term D1 B / (2R) vanishes.
        b = math.hypot(x, y)
        assert m1_error(o1, o2, t, R, dphi, baseline_known=True) == pytest.approx(
            (normalised_error_xy(x, y, D1, R) - b / (2 * R)) * D1 * dphi, rel=1e-10
        )


def test_m1_vectorised_and_colinear_is_infinite() -> None:
    t = np.array([[6.0, 0.0], [3.0, 2.0], [8.0, 0.0]])
    out = m1_error((0.0, 0.0), (4.0, 0.0), t, R, 0.0035, baseline_known=True)
    assert out.shape == (3,) and math.isinf(out[0]) and math.isinf(out[2]) and np.isfinite(out[1])


def test_m1_is_first_order_worst_case_of_eq1_and_eq3() -> None:
    """Perturb phi1, phi2 and alpha by +-dphi through Eqs. (1) and (3): the worst D1 change matches M1."""
    o2 = np.array(OPT.o2_xy_pair[0])
    b = float(np.hypot(*o2))
    phi1 = OPT.phi1_rad
    phi2 = math.pi - phi1 - math.asin(b * math.sin(phi1) / math.hypot(D1 - o2[0], o2[1]))
    alpha = 2 * math.asin(R / b)
    dphi = 1e-6
    worst = 0.0
    for s1 in (-1, 1):
        for s2 in (-1, 1):
            for sa in (-1, 1):
                bb = baseline_exact(alpha / 2 + sa * dphi / 2, -alpha / 2 - sa * dphi / 2, R)
                d1, _ = triangulate(bb, phi1 + s1 * dphi, phi2 + s2 * dphi)
                worst = max(worst, abs(d1 - D1))
    # The approximate dB = B^2/(2R) dalpha exceeds the exact B sqrt(B^2-R^2)/(2R) by <0.4 %.
    m1_exact = m1_error((0, 0), o2, (D1, 0), R, dphi, baseline_known=False, exact_baseline=True)
    assert worst == pytest.approx(m1_exact, rel=1e-4)


def test_error_map_grid() -> None:
    emap = error_map(D1, R, (-1.5, 7.5, -4.0, 4.0), 0.02)
    assert emap.error.shape == (emap.y_m.size, emap.x_m.size) == (401, 451)
    j, i = np.unravel_index(np.argmin(emap.error), emap.error.shape)
    # notes: 0.02 m grid minimum at (1.10, +-1.86).
    assert emap.x_m[i] == pytest.approx(1.10, abs=0.011) and abs(emap.y_m[j]) == pytest.approx(1.86, abs=0.011)
    assert emap.error[j, i] >= OPT.normalised_error
    assert np.allclose(emap.error, emap.error[::-1], equal_nan=True)  # symmetric about the O1-T line
    assert np.all(np.isinf(emap.error[200]))  # y = 0 row
    sq = error_map(D1, R, 2.0, 0.5)
    assert sq.x_m[0] == pytest.approx(1.0) and sq.x_m[-1] == pytest.approx(5.0) and sq.y_m[0] == pytest.approx(-2.0)


def test_optimal_positions_world_rotate_with_the_pair() -> None:
    o1, t = np.array([1.0, 2.0]), np.array([1.0, 8.0])  # T straight up, 6 m away
    pa, pb, cfg = optimal_positions_world(o1, t, R)
    assert cfg.baseline_m == pytest.approx(OPT.baseline_m, abs=1e-6)
    for p in (pa, pb):
        assert math.hypot(*(p - o1)) == pytest.approx(OPT.baseline_m, abs=1e-6)
        ang = abs(wrap_angle(math.atan2(p[1] - o1[1], p[0] - o1[0]) - math.pi / 2))
        assert ang == pytest.approx(OPT.phi1_rad, abs=1e-6)
    assert pa[0] < o1[0] < pb[0]


def test_pair_position_error_formula_and_degenerate() -> None:
    sig = 0.0035
    e = pair_position_error((0, 0), (4, 0), (2, 2), sig)
    assert e == pytest.approx(sig * math.hypot(math.sqrt(8), math.sqrt(8)) / 1.0, rel=1e-12)
    with_b = pair_position_error((0, 0), (4, 0), (2, 2), sig, sigma_baseline_m=0.1)
    assert with_b == pytest.approx(math.hypot(e, math.sqrt(8) * 0.1 / 4), rel=1e-12)
    assert pair_position_error((0, 0), (4, 0), (6, 0), sig) == MAX_ERROR_M
    assert pair_position_error((0, 0), (0, 0), (6, 1), sig) == MAX_ERROR_M
    # A better-conditioned pair ranks first.
    assert pair_position_error((0, 0), (0, 4), (3, 3), sig) < pair_position_error((0, 0), (1, 1), (3, 3.2), sig)


def _mc_rms(o1: np.ndarray, o2: np.ndarray, t: np.ndarray, sig: float, n: int, rng: np.random.Generator) -> float:
    """Seeded Monte Carlo: noisy bearings -> signed inner angles -> Eq. (1) -> position; RMS error."""
    psi12 = math.atan2(*(o2 - o1)[::-1])
    th1 = math.atan2(*(t - o1)[::-1]) + rng.normal(0, sig, n)
    th2 = math.atan2(*(t - o2)[::-1]) + rng.normal(0, sig, n)
    a1 = np.abs(wrap_angle(th1 - psi12))
    a2 = np.abs(wrap_angle(psi12 + math.pi - th2))
    d1, _ = triangulate(np.full(n, float(np.hypot(*(o2 - o1)))), a1, a2)
    xy = o1 + d1[:, None] * np.column_stack([np.cos(th1), np.sin(th1)])
    return float(np.sqrt(np.mean(np.sum((xy - t) ** 2, axis=1))))


def test_monte_carlo_matches_the_model_where_sin_phi0_above_0_3() -> None:
    """The paper's geometry (O1 = 0, T at 6 m, camera 2 over Fig. 4's map), 1 px = 0.333 deg bearing noise.

    Empirical RMS position error within 15 % of pair_position_error wherever sin phi0 > 0.3,
    with poses known and with a mutual-calibration baseline error.
    """
    rng = np.random.default_rng(2024)
    sig = math.radians(360 / 1080)  # 1 px of the 1080-px panoramas
    o1, t = np.zeros(2), np.array([D1, 0.0])
    ratios = []
    for x in np.arange(-1.0, 7.01, 1.0):
        for y in (0.5, 1.0, 2.0, 3.0, -1.5, -4.0):
            o2 = np.array([x, y])
            v1, v2 = t - o1, t - o2
            sin0 = abs(v1[0] * v2[1] - v1[1] * v2[0]) / (np.hypot(*v1) * np.hypot(*v2))
            if sin0 <= 0.3:
                continue
            ratios.append(_mc_rms(o1, o2, t, sig, 4000, rng) / pair_position_error(o1, o2, t, sig))
    assert len(ratios) > 25
    assert np.all(np.abs(np.array(ratios) - 1) < 0.15), ratios
    # With per-frame mutual calibration (1 px on each boundary): the triangle scales about O1.
    o2 = np.array(OPT.o2_xy_pair[0])
    b = float(np.hypot(*o2))
    n = 4000
    half = math.asin(R / b)
    bs = np.array([baseline_exact(half + e1, -half + e2, R) for e1, e2 in rng.normal(0, sig, (n, 2))])
    psi12 = math.atan2(o2[1], o2[0])
    th1 = math.atan2(*(t - o1)[::-1]) + rng.normal(0, sig, n)
    th2 = math.atan2(*(t - o2)[::-1]) + rng.normal(0, sig, n)
    d1, _ = triangulate(bs, np.abs(wrap_angle(th1 - psi12)), np.abs(wrap_angle(psi12 + math.pi - th2)))
    xy = d1[:, None] * np.column_stack([np.cos(th1), np.sin(th1)])
    rms = float(np.sqrt(np.mean(np.sum((xy - t) ** 2, axis=1))))
    sigma_b = b * math.sqrt(b * b - R * R) / (2 * R) * math.sqrt(2) * sig
    assert rms == pytest.approx(pair_position_error(o1, o2, t, sig, sigma_baseline_m=sigma_b), rel=0.15)


@pytest.mark.parametrize(("d1", "r"), [(0.3, 0.18), (6.0, 0.0), (-1.0, 0.18)])
def test_optimal_configuration_rejects_bad_input(d1: float, r: float) -> None:
    from common.errors import GeometryError

    with pytest.raises(GeometryError):
        optimal_configuration(d1, r)


def _pair_error_numpy(o1: np.ndarray, o2: np.ndarray, t: np.ndarray, sig: float, sig_b: float) -> float:
    """The error model written with numpy vectors (the formula of pair_position_error, independently)."""
    v1, v2 = t - o1, t - o2
    d1, d2, b = np.linalg.norm(v1), np.linalg.norm(v2), np.linalg.norm(o2 - o1)
    if min(d1, d2, b) <= 0:
        return MAX_ERROR_M
    sin0 = abs(float(v1[0] * v2[1] - v1[1] * v2[0])) / (d1 * d2)
    if sin0 * MAX_ERROR_M <= sig * math.hypot(d1, d2):
        return MAX_ERROR_M
    return min(math.sqrt((sig * math.hypot(d1, d2) / sin0) ** 2 + (d1 * sig_b / b) ** 2), MAX_ERROR_M)


def test_batched_and_float_pair_errors_equal_the_scalar_one() -> None:
    """pair_position_errors (N pairs at once) and pair_error_f (plain floats) agree with pair_position_error,
    degenerate geometry included (target on the baseline line, at a camera, cameras at one place)."""
    rng = np.random.default_rng(5)
    n = 400
    o1 = rng.uniform(-5, 5, (n, 2))
    o2 = rng.uniform(-5, 5, (n, 2))
    t = rng.uniform(-5, 5, (n, 2))
    t[:20] = o1[:20] + rng.uniform(-2, 3, (20, 1)) * (o2[:20] - o1[:20])  # colinear
    t[20:30] = o2[20:30]  # at camera 2
    o2[30:40] = o1[30:40]  # zero baseline
    sig = rng.uniform(1e-4, 0.02, n)
    sig_b = np.where(rng.random(n) < 0.5, 0.0, rng.uniform(0, 0.2, n))
    scalar = np.array([pair_position_error(o1[k], o2[k], t[k], sig[k], sig_b[k]) for k in range(n)])
    reference = np.array([_pair_error_numpy(o1[k], o2[k], t[k], sig[k], sig_b[k]) for k in range(n)])
    np.testing.assert_allclose(scalar, reference, rtol=1e-12)
    assert np.count_nonzero(scalar == MAX_ERROR_M) >= 30
    np.testing.assert_allclose(pair_position_errors(o1, o2, t, sig, sig_b), scalar, rtol=1e-12)
    floats = [pair_error_f(*o1[k], *o2[k], *t[k], float(sig[k]), float(sig_b[k])) for k in range(n)]
    assert floats == scalar.tolist()
    # One target for many pairs, scalar sigmas.
    one = pair_position_errors(o1, o2, t[50], 0.01)
    np.testing.assert_allclose(one, [pair_position_error(o1[k], o2[k], t[50], 0.01) for k in range(n)], rtol=1e-12)
