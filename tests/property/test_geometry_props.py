"""Property tests: the geometry round-trips for any well-posed configuration."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from common.cameras import CylindricalCamera, PinholeCamera, PtzCamera, design_pal, rotation_from_rvec
from common.error_model import m1_error, normalised_error_xy, optimal_configuration
from common.geometry import (
    baseline_exact,
    intersect_rays,
    localize_pair,
    sighting_bearing,
    triangulate,
    wrap_angle,
)

coord = st.floats(-20.0, 20.0, allow_nan=False)
angle = st.floats(-math.pi, math.pi, allow_nan=False)
SETTINGS = settings(max_examples=150, deadline=None)
PAL, PAL_CAM = design_pal()


def _sin_phi0(o1: np.ndarray, o2: np.ndarray, t: np.ndarray) -> float:
    v1, v2 = t - o1, t - o2
    return abs(v1[0] * v2[1] - v1[1] * v2[0]) / (np.hypot(*v1) * np.hypot(*v2))


@SETTINGS
@given(coord, coord, coord, coord, coord, coord)
def test_pair_localises_exactly_without_noise(x1: float, y1: float, x2: float, y2: float, tx: float, ty: float) -> None:
    o1, o2, t = np.array([x1, y1]), np.array([x2, y2]), np.array([tx, ty])
    assume(min(np.hypot(*(o2 - o1)), np.hypot(*(t - o1)), np.hypot(*(t - o2))) > 0.5)
    assume(_sin_phi0(o1, o2, t) > 0.05)
    b1 = math.atan2(ty - y1, tx - x1)
    b2 = math.atan2(ty - y2, tx - x2)
    # Widths not trusted (huge sigma_w): Eq. (1) everywhere off the line, exact without noise.
    fix = localize_pair(o1, b1, 0.05, o2, b2, 0.05, 0.0035, 1e9)
    assert fix.converges
    assert np.allclose(fix.xy, t, atol=1e-6 * (1 + np.abs(t).max()))
    ray = intersect_rays(np.array([o1, o2]), np.array([b1, b2]), 0.0035)
    assert np.allclose(ray.xy, t, atol=1e-6 * (1 + np.abs(t).max()))


@SETTINGS
@given(st.floats(0.05, 10.0), st.floats(0.01, 3.0), st.floats(0.01, 3.0))
def test_triangulation_satisfies_the_law_of_sines(b: float, phi1: float, phi2: float) -> None:
    assume(phi1 + phi2 < math.pi - 0.01)
    d1, d2 = triangulate(b, phi1, phi2)
    phi0 = math.pi - phi1 - phi2
    assert math.isclose(d1 / math.sin(phi2), b / math.sin(phi0), rel_tol=1e-9)
    assert math.isclose(d2 / math.sin(phi1), b / math.sin(phi0), rel_tol=1e-9)


@SETTINGS
@given(st.floats(0.05, 1.0), st.floats(1.05, 50.0), angle)
def test_eq3_inverts_tangent_rays(radius: float, ratio: float, axis: float) -> None:
    b = radius * ratio
    half = math.asin(radius / b)
    left, right = axis + half, axis - half
    assert math.isclose(baseline_exact(left, right, radius), b, rel_tol=1e-9)
    assert abs(wrap_angle(sighting_bearing(wrap_angle(left), wrap_angle(right)) - axis)) < 1e-9


@SETTINGS
@given(st.floats(-2.0, 8.0), st.floats(0.1, 5.0), st.floats(2.0, 12.0), st.floats(0.05, 0.5))
def test_normalised_map_symmetric_and_above_its_minimum(x: float, y: float, d1: float, r: float) -> None:
    assume(d1 > 4 * r)
    e_up = normalised_error_xy(x, y, d1, r)
    assert e_up == normalised_error_xy(x, -y, d1, r)
    assert math.isclose(m1_error((0, 0), (x, y), (d1, 0), r, 1.0, False), e_up * d1, rel_tol=1e-9)
    if math.hypot(d1 - x, y) >= d1 / 2 and math.hypot(x, y) > 2 * r:
        assert e_up >= optimal_configuration(d1, r).normalised_error * (1 - 1e-9)


@SETTINGS
@given(st.floats(0.0, 1079.99), st.floats(-0.5, 161.5))
def test_annular_round_trip(u: float, v: float) -> None:
    x, y = PAL.annular_from_pano(u, v)
    u2, v2 = PAL.pano_from_annular(x, y)
    assert abs((float(u2) - u + 540) % 1080 - 540) < 1e-6 and abs(float(v2) - v) < 1e-6


@SETTINGS
@given(coord, coord, st.floats(0.0, 2.5), st.integers(-1, 1).filter(bool), angle)
def test_cylindrical_projection_round_trip(x: float, y: float, z: float, direction: int, b0: float) -> None:
    assume(math.hypot(x, y) > 0.2)
    cam = CylindricalCamera(1080, 162, PAL_CAM.f_v_px, PAL_CAM.v0_px, 1.1, direction=direction, bearing0_rad=b0)
    u, v = cam.project(np.array([x, y, z]))
    assert 0 <= float(u) < 1080
    assert abs(wrap_angle(cam.bearing_from_col(float(u)) - math.atan2(y, x))) < 1e-9
    assert math.isclose(cam.point_height(float(v), math.hypot(x, y)), z, abs_tol=1e-9)


@SETTINGS
@given(angle, st.floats(-1.2, 1.2), st.floats(1.0, 20.0), st.floats(0, 1279), st.floats(0, 719))
def test_ptz_pixel_ray_round_trip(pan: float, tilt: float, zoom: float, u: float, v: float) -> None:
    cam = PtzCamera(1.0, 2.0, 3.0, 1280, 720, math.radians(60), pan, tilt, zoom).pinhole()
    ray = cam.ray_world(np.array([[u, v]]))
    uv, in_front = cam.project(cam.center_world + 4.0 * ray)
    assert in_front[0] and np.allclose(uv[0], [u, v], atol=1e-6)


@SETTINGS
@given(st.floats(1.0, 8.0), st.floats(-3.0, 11.0), st.floats(-0.02, 0.02), st.floats(0.1, 0.4))
def test_pair_near_the_baseline_stays_close(b: float, tx: float, ty: float, body_r: float) -> None:
    """Within the size-ratio zone, cylinder widths keep the estimate within the h^2 model bias of the truth."""
    o1, o2, t = np.zeros(2), np.array([b, 0.0]), np.array([tx, ty])
    d1, d2 = float(np.hypot(*t)), float(np.hypot(*(t - o2)))
    assume(min(d1, d2) > 2 * body_r + 0.3)
    w1, w2 = 2 * math.asin(body_r / d1), 2 * math.asin(body_r / d2)
    fix = localize_pair(o1, math.atan2(ty, tx), w1, o2, math.atan2(ty, tx - b), w2, 0.0035, 0.007)
    assert fix.converges
    assert float(np.hypot(*(fix.xy - t))) < 0.01 + ty * ty / min(d1, d2)


@SETTINGS
@given(
    st.tuples(angle, angle, angle),
    st.tuples(coord, coord, st.floats(0.5, 30.0)),
    st.floats(200.0, 5000.0),
    st.floats(0.5, 2.0),
    st.floats(-1e3, 1e3).filter(lambda s: abs(s) > 1e-3),
)
def test_projection_matrix_decomposes_back(
    rv: tuple[float, float, float], t: tuple[float, float, float], fx: float, aspect: float, scale: float
) -> None:
    """Any P = s K [R | t] (s of either sign) gives back K, R and t."""
    rot = rotation_from_rvec(np.array(rv) * 0.99)
    k = np.array([[fx, 0.0, 640.0], [0.0, fx * aspect, 360.0], [0.0, 0.0, 1.0]])
    p = scale * k @ np.column_stack([rot, np.array(t)])
    cam = PinholeCamera.from_calibration({"model": "pinhole", "image_size": [1280, 720], "P": p.tolist()}, "prop")
    assert np.allclose(cam.k, k, rtol=1e-7, atol=1e-6)
    assert np.allclose(cam.r, rot, atol=1e-8)
    assert np.allclose(cam.t, t, rtol=1e-7, atol=1e-6)
