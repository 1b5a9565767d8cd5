"""Eqs. (1)-(3), N-ray intersection and the automatic Eq. (1)/(2) choice."""

from __future__ import annotations

import math

import numpy as np
import pytest

from common.angles import wrap_angle
from common.errors import GeometryError
from common.geometry import (
    MAX_SIZE_RATIO_OFFSET_RAD,
    baseline_exact,
    baseline_from_alpha,
    intersect_rays,
    localize_pair,
    sighting_bearing,
    size_ratio,
    triangulate,
)


def _bearing(src: np.ndarray, dst: np.ndarray) -> float:
    d = np.asarray(dst, float) - np.asarray(src, float)
    return math.atan2(d[1], d[0])


def _inner_angles(o1: np.ndarray, o2: np.ndarray, t: np.ndarray) -> tuple[float, float]:
    a1 = abs(wrap_angle(_bearing(o1, t) - _bearing(o1, o2)))
    a2 = abs(wrap_angle(_bearing(o2, t) - _bearing(o2, o1)))
    return a1, a2


@pytest.mark.parametrize(
    ("o2", "t"),
    [
        ((4.0, 0.0), (2.0, 3.0)),
        ((2.1655, 0.0), (3.0, -5.0)),
        ((1.0, 1.0), (6.0, 0.0)),
        ((-3.0, 2.0), (0.5, 7.0)),
        ((5.0, 5.0), (5.2, -0.3)),
    ],
)
def test_noise_free_rays_triangulate_to_the_source(o2: tuple[float, float], t: tuple[float, float]) -> None:
    """Eq. (1) on exact inner angles returns the exact distances, and localize_pair the exact point."""
    o1, o2a, ta = np.zeros(2), np.array(o2), np.array(t)
    b = float(np.hypot(*o2a))
    phi1, phi2 = _inner_angles(o1, o2a, ta)
    d1, d2 = triangulate(b, phi1, phi2)
    assert d1 == pytest.approx(float(np.hypot(*ta)), rel=1e-12)
    assert d2 == pytest.approx(float(np.hypot(*(ta - o2a))), rel=1e-12)
    fix = localize_pair(o1, _bearing(o1, ta), 0.05, o2a, _bearing(o2a, ta), 0.05, 0.0035, 0.007)
    assert fix.converges and fix.method == "triangulation"
    assert np.allclose(fix.xy, ta, atol=1e-9)
    assert fix.phi0_rad == pytest.approx(math.pi - phi1 - phi2, abs=1e-12)


def test_triangulate_vectorised_and_degenerate() -> None:
    d1, d2 = triangulate(np.array([2.0, 2.0]), np.array([math.pi / 4, 2.0]), np.array([math.pi / 4, 1.5]))
    assert d1[0] == pytest.approx(math.sqrt(2)) and d2[0] == pytest.approx(math.sqrt(2))
    assert math.isnan(d1[1]) and math.isnan(d2[1])
    with pytest.raises(GeometryError, match="converging"):
        triangulate(2.0, 2.0, 1.5)
    with pytest.raises(GeometryError):
        triangulate(0.0, 0.5, 0.5)


@pytest.mark.parametrize(
    ("t_x", "c1", "c2"),
    [(1.0, 1, 1), (2.5, 1, 1), (3.9, 1, 1), (6.0, 1, -1), (10.0, 1, -1), (-2.0, -1, 1), (-0.5, -1, 1)],
)
def test_size_ratio_exact_when_colinear(t_x: float, c1: int, c2: int) -> None:
    """Eq. (2): widths ~ W/D give the exact distances between, beyond O2 and beyond O1."""
    b, width_m = 4.0, 0.45
    d1_true, d2_true = abs(t_x), abs(t_x - b)
    d1, d2 = size_ratio(b, width_m / d1_true, width_m / d2_true, c1, c2)
    assert (d1, d2) == (pytest.approx(d1_true, rel=1e-12), pytest.approx(d2_true, rel=1e-12))


def test_size_ratio_rejects_impossible() -> None:
    with pytest.raises(GeometryError):
        size_ratio(4.0, 0.2, 0.1, 1, -1)  # beyond O2 but looks bigger from O1
    with pytest.raises(GeometryError):
        size_ratio(4.0, 0.0, 0.1, 1, 1)


@pytest.mark.parametrize("b_true", [0.5, 1.0, 2.1655, 4.0, 8.0])
@pytest.mark.parametrize("axis_bearing", [0.3, math.pi - 0.01, -2.0])
def test_eq3_exact_on_a_cylinder_silhouette(b_true: float, axis_bearing: float) -> None:
    """Occluding boundaries of a cylinder (tangent rays) give back its distance and axis bearing."""
    r = 0.18
    half = math.asin(r / b_true)  # tangent ray half-angle
    left, right = wrap_angle(axis_bearing + half), wrap_angle(axis_bearing - half)
    assert baseline_exact(left, right, r) == pytest.approx(b_true, rel=1e-12)
    assert baseline_exact(right, left, r) == pytest.approx(b_true, rel=1e-12)
    assert baseline_from_alpha(2 * half, r) == pytest.approx(b_true, rel=1e-12)
    assert wrap_angle(sighting_bearing(left, right) - axis_bearing) == pytest.approx(0.0, abs=1e-12)
    # The tangent points really are on the cylinder: distance from the axis to each ray is R.
    axis = b_true * np.array([math.cos(axis_bearing), math.sin(axis_bearing)])
    for bnd in (left, right):
        d = np.array([math.cos(bnd), math.sin(bnd)])
        assert abs(axis[0] * d[1] - axis[1] * d[0]) == pytest.approx(r, rel=1e-12)


def test_eq3_rejects_bad_alpha() -> None:
    for alpha in (0.0, math.pi, -0.1):
        with pytest.raises(GeometryError):
            baseline_from_alpha(alpha, 0.18)


@pytest.mark.parametrize("n", [2, 3, 5])
def test_intersect_rays_noise_free(n: int) -> None:
    rng = np.random.default_rng(n)
    target = np.array([2.0, 3.0])
    origins = rng.uniform(-4, 8, (n, 2))
    origins[0] = [-3.0, -1.0]
    origins[1] = [7.0, -1.0]
    bearings = np.arctan2(target[1] - origins[:, 1], target[0] - origins[:, 0])
    fix = intersect_rays(origins, bearings, np.full(n, 0.0035))
    assert np.allclose(fix.xy, target, atol=1e-9)
    assert fix.residual_rms < 1e-6
    assert fix.cov.shape == (2, 2) and np.all(np.linalg.eigvalsh(fix.cov) > 0)


def test_intersect_rays_covariance_matches_monte_carlo() -> None:
    rng = np.random.default_rng(11)
    target = np.array([1.0, 4.0])
    origins = np.array([[-3.0, 0.0], [3.0, 0.0], [0.0, -1.0]])
    sig = np.array([0.004, 0.006, 0.005])
    clean = np.arctan2(target[1] - origins[:, 1], target[0] - origins[:, 0])
    pts = np.array([intersect_rays(origins, clean + rng.normal(0, sig), sig).xy for _ in range(1500)])
    cov_mc = np.cov(pts.T)
    cov_model = intersect_rays(origins, clean, sig).cov
    assert np.allclose(np.sqrt(np.diag(cov_mc)), np.sqrt(np.diag(cov_model)), rtol=0.1)
    assert np.allclose(pts.mean(axis=0), target, atol=0.01)


@pytest.mark.parametrize(
    ("origins", "bearings"),
    [
        ([[0.0, 0.0]], [0.0]),  # one ray
        ([[0.0, 0.0], [0.0, 1.0]], [0.0, 0.0]),  # parallel
        ([[0.0, 0.0], [4.0, 0.0]], [math.pi / 2, -math.pi / 2 - 0.3]),  # meet behind
    ],
)
def test_intersect_rays_rejects_degenerate(origins: list[list[float]], bearings: list[float]) -> None:
    with pytest.raises(GeometryError):
        intersect_rays(origins, bearings, 0.01)


def _cyl_width(d: float, body_r: float = 0.225) -> float:
    return 2 * math.asin(body_r / d)


@pytest.mark.parametrize("t", [(1.5, 0.0), (3.0, 0.02), (6.5, 0.0), (-2.0, 0.01)])
def test_localize_pair_uses_size_ratio_near_the_baseline_and_is_exact_on_it(t: tuple[float, float]) -> None:
    o1, o2, ta = np.zeros(2), np.array([4.0, 0.0]), np.array(t)
    d1, d2 = float(np.hypot(*ta)), float(np.hypot(*(ta - o2)))
    fix = localize_pair(
        o1, _bearing(o1, ta), _cyl_width(d1), o2, _bearing(o2, ta), _cyl_width(d2), math.radians(0.2), math.radians(0.4)
    )
    assert fix.method == "size_ratio" and fix.converges
    if t[1] == 0.0:
        assert fix.d1_m == pytest.approx(d1, rel=1e-12) and fix.d2_m == pytest.approx(d2, rel=1e-12)
        assert np.allclose(fix.xy, ta, atol=1e-12)
    else:
        assert np.hypot(*(fix.xy - ta)) < 0.01


@pytest.mark.parametrize(
    ("h_m", "expected"),
    # W = 0.45 m, sigma_phi/sigma_w = 1/2: crossover h* = 0.225 m (notes section 3).
    [(0.10, "size_ratio"), (0.20, "size_ratio"), (0.25, "triangulation"), (0.5, "triangulation")],
)
def test_localize_pair_crossover(h_m: float, expected: str) -> None:
    o1, o2, ta = np.zeros(2), np.array([4.0, 0.0]), np.array([2.0, h_m])
    d1, d2 = float(np.hypot(*ta)), float(np.hypot(*(ta - o2)))
    w1 = 2 * math.atan(0.45 / (2 * d1))
    w2 = 2 * math.atan(0.45 / (2 * d2))
    sig = math.radians(0.2)
    fix = localize_pair(o1, _bearing(o1, ta), w1, o2, _bearing(o2, ta), w2, sig, 2 * sig)
    assert fix.method == expected and fix.converges


def test_localize_pair_never_uses_size_ratio_far_off_the_line() -> None:
    o1, o2, ta = np.zeros(2), np.array([4.0, 0.0]), np.array([2.0, 2.0])
    offset = math.atan2(2.0, 2.0)
    assert offset > MAX_SIZE_RATIO_OFFSET_RAD
    fix = localize_pair(o1, _bearing(o1, ta), 1.0, o2, _bearing(o2, ta), 1.0, 0.01, 0.0)
    assert fix.method == "triangulation"


def test_localize_pair_reports_diverging_rays() -> None:
    o1, o2 = np.zeros(2), np.array([4.0, 0.0])
    fix = localize_pair(o1, math.radians(60), 0.05, o2, math.radians(-120), 0.05, 0.0035, 0.007)
    assert not fix.converges and np.all(np.isnan(fix.xy))
    with pytest.raises(GeometryError):
        localize_pair(o1, 0.1, 0.05, o1, 0.2, 0.05, 0.0035, 0.007)


def test_room_accuracy_with_automatic_choice() -> None:
    """notes section 6, configuration A (6 x 8 m room, cameras 3 m apart on a wall), poses known.

    1 px = 0.2 deg Gaussian bearing noise, 2 px width noise, W = 0.45 m: mean error < 6 cm (notes: 3.6 cm),
    and on the baseline line the automatic size-ratio fallback beats triangulation alone.
    """
    rng = np.random.default_rng(7)
    o1, o2 = np.array([1.5, 0.0]), np.array([4.5, 0.0])
    sig, sig_w, width_m = math.radians(0.2), math.radians(0.4), 0.45
    xs, ys = np.meshgrid(np.arange(0.05, 6.0, 0.1), np.arange(0.05, 8.0, 0.1))
    pts = np.column_stack([xs.ravel(), ys.ravel()])
    pts = pts[(np.hypot(*(pts - o1).T) > 0.3) & (np.hypot(*(pts - o2).T) > 0.3)]

    def run(targets: np.ndarray, sigma_w_claimed: float) -> np.ndarray:
        errs = []
        for t in targets:
            d1, d2 = float(np.hypot(*(t - o1))), float(np.hypot(*(t - o2)))
            b1 = _bearing(o1, t) + rng.normal(0, sig)
            b2 = _bearing(o2, t) + rng.normal(0, sig)
            w1 = 2 * math.atan(width_m / (2 * d1)) + rng.normal(0, sig_w)
            w2 = 2 * math.atan(width_m / (2 * d2)) + rng.normal(0, sig_w)
            fix = localize_pair(o1, b1, w1, o2, b2, w2, sig, sigma_w_claimed)
            errs.append(float(np.hypot(*(fix.xy - t))) if fix.converges else math.inf)
        return np.array(errs)

    errs = run(pts, sig_w)
    assert np.all(np.isfinite(errs))
    assert errs.mean() < 0.06 and np.median(errs) < 0.04
    line = np.array([[x, 0.05] for x in np.arange(0.2, 6.0, 0.1) if min(abs(x - 1.5), abs(x - 4.5)) > 0.3] * 20)
    auto = run(line, sig_w)
    tri_only = run(line, 1e9)
    assert np.sqrt(np.mean(auto**2)) < 0.5 * np.sqrt(np.mean(np.where(np.isfinite(tri_only), tri_only, 1e3) ** 2))


def test_scalar_paths_equal_the_array_paths() -> None:
    """wrap_angle and triangulate on plain floats (the per-candidate hot path) give the array results."""
    rng = np.random.default_rng(11)
    a = rng.uniform(-20, 20, 300)
    assert [wrap_angle(float(x)) for x in a] == pytest.approx(wrap_angle(a).tolist(), abs=1e-12)
    assert all(-math.pi <= wrap_angle(float(x)) < math.pi for x in a)
    assert wrap_angle(3) == 3.0 and isinstance(wrap_angle(3), float) and wrap_angle(4) == pytest.approx(4 - 2 * math.pi)
    b = rng.uniform(0.5, 8, 300)
    p1, p2 = rng.uniform(0, 2, 300), rng.uniform(0, 2, 300)
    d1, d2 = triangulate(b, p1, p2)
    for k in range(300):
        if np.isfinite(d1[k]):
            assert triangulate(float(b[k]), float(p1[k]), float(p2[k])) == pytest.approx((d1[k], d2[k]), rel=1e-12)
        else:
            with pytest.raises(GeometryError):
                triangulate(float(b[k]), float(p1[k]), float(p2[k]))
