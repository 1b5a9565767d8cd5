"""Camera models: cylindrical (Step 3), annular PAL (Steps 1-2), pinhole and PTZ."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from common.cameras import (
    AnnularModel,
    CylindricalCamera,
    PinholeCamera,
    PtzCamera,
    calibrate_cylindrical,
    center_from_lines,
    design_pal,
    fit_radial_polynomial,
    rotation_from_rvec,
)
from common.errors import CalibrationError, ConfigError

CAM = CylindricalCamera(width_px=1080, height_px=162, f_v_px=256.0, v0_px=93.0, height_m=1.1)


# --------------------------------------------------------------------------------------------------
# Cylindrical camera
# --------------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("u", "bearing_rad"),
    [(0.0, 0.0), (270.0, math.pi / 2), (540.0, -math.pi), (810.0, -math.pi / 2), (1079.0, -2 * math.pi / 1080)],
)
def test_bearing_from_col_table(u: float, bearing_rad: float) -> None:
    assert CAM.bearing_from_col(u) == pytest.approx(bearing_rad, abs=1e-12)
    assert CAM.f_h_px == pytest.approx(1080 / (2 * math.pi))


@pytest.mark.parametrize("direction", [1, -1])
@pytest.mark.parametrize("bearing0", [0.0, 1.3, -2.9])
def test_col_bearing_round_trip(direction: int, bearing0: float) -> None:
    cam = CylindricalCamera(1080, 162, 256.0, 93.0, 1.1, direction=direction, bearing0_rad=bearing0)
    u = np.linspace(0, 1079.99, 997)
    back = cam.col_from_bearing(cam.bearing_from_col(u))
    assert np.all((back >= 0) & (back < 1080))
    assert np.allclose(back, u, atol=1e-9)


@pytest.mark.parametrize(("v", "elev_deg"), [(93.0, 0.0), (93.0 - 256.0, 45.0), (93.0 + 256.0, -45.0)])
def test_elevation_table(v: float, elev_deg: float) -> None:
    assert math.degrees(CAM.elevation_from_row(v)) == pytest.approx(elev_deg, abs=1e-9)
    assert CAM.row_from_elevation(math.radians(elev_deg)) == pytest.approx(v, abs=1e-9)


@pytest.mark.parametrize(
    ("xyz", "expected_distance"),
    [((3.0, 4.0, 0.0), 5.0), ((-2.0, 0.5, 0.0), math.hypot(2.0, 0.5)), ((0.0, -6.0, 0.0), 6.0)],
)
def test_project_floor_point_gives_distance_and_bearing(
    xyz: tuple[float, float, float], expected_distance: float
) -> None:
    u, v = CAM.project(np.array(xyz))
    assert CAM.floor_distance(float(v)) == pytest.approx(expected_distance, rel=1e-12)
    assert CAM.bearing_from_col(float(u)) == pytest.approx(math.atan2(xyz[1], xyz[0]), abs=1e-12)


def test_head_height_from_row_at_known_distance() -> None:
    pts = np.array([[4.0, 1.0, 1.75], [-1.0, -2.0, 1.6], [0.5, 7.0, 0.3]])
    _u, v = CAM.project(pts)
    rho = np.hypot(pts[:, 0], pts[:, 1])
    assert np.allclose(CAM.point_height(v, rho), pts[:, 2])
    assert np.allclose(CAM.elevation_from_row(v), np.arctan2(pts[:, 2] - 1.1, rho))


def test_floor_distance_above_horizon_is_infinite() -> None:
    assert math.isinf(CAM.floor_distance(50.0))
    out = CAM.floor_distance(np.array([50.0, 93.0, 93.0 + 256.0 * 1.1 / 2.0]))
    assert math.isinf(out[0]) and math.isinf(out[1]) and out[2] == pytest.approx(2.0)


def test_metric_width() -> None:
    w_px = 2 * CAM.f_h_px * math.atan(0.45 / (2 * 3.0))
    assert CAM.metric_width(w_px, 3.0) == pytest.approx(0.45)


def test_cylindrical_model_round_trip() -> None:
    back = CylindricalCamera.from_model(CAM.to_model(), height_m=1.1)
    assert back == CAM


@pytest.mark.parametrize(
    "kwargs", [{"f_v_px": 0.0}, {"f_v_px": float("nan")}, {"direction": 0}, {"width_px": 4}, {"v0_px": float("inf")}]
)
def test_cylindrical_rejects_bad_parameters(kwargs: dict[str, float]) -> None:
    base: dict[str, float] = {"width_px": 1080, "height_px": 162, "f_v_px": 256.0, "v0_px": 93.0, "height_m": 1.1}
    with pytest.raises(ConfigError):
        CylindricalCamera(**{**base, **kwargs})  # type: ignore[arg-type]


def _scene(rng: np.random.Generator, n: int) -> np.ndarray:
    rho = rng.uniform(1.0, 8.0, n)
    th = rng.uniform(-math.pi, math.pi, n)
    z = rng.uniform(0.0, 2.2, n)
    return np.column_stack([rho * np.cos(th), rho * np.sin(th), z])


@pytest.mark.parametrize("direction", [1, -1])
def test_calibration_exact_without_noise(direction: int) -> None:
    truth = CylindricalCamera(1080, 162, 250.0, 88.0, 1.05, direction=direction, bearing0_rad=0.7)
    pts = _scene(np.random.default_rng(1), 3)
    u, v = truth.project(pts)
    cal = calibrate_cylindrical(pts, np.column_stack([u, v]), 1080, 162)
    assert cal.camera.direction == direction
    assert cal.camera.f_v_px == pytest.approx(250.0, rel=1e-9)
    assert cal.camera.v0_px == pytest.approx(88.0, abs=1e-7)
    assert cal.camera.height_m == pytest.approx(1.05, rel=1e-9)
    assert cal.camera.bearing0_rad == pytest.approx(0.7, abs=1e-9)
    assert cal.rms_px < 1e-6


@pytest.mark.parametrize("seed", [0, 1, 2, 3, 4, 5])
def test_calibration_recovers_parameters_from_noisy_points(seed: int) -> None:
    """A 20-mark calibration scene (poles at 2, 3, 5, 8 m, marks 0.1-1.9 m high) with 1 px Gaussian noise.

    Stated tolerance (~4 standard errors of this design): v0 within 2 px, f_v within 3 %,
    H_c within 3 cm, bearing offset within 0.15 deg; the residual RMS reflects the noise.
    """
    rng = np.random.default_rng(seed)
    truth = CylindricalCamera(1080, 162, 160.0, 70.0, 1.05, bearing0_rad=-0.4)
    rho = np.repeat([2.0, 3.0, 5.0, 8.0], 5)
    z = np.tile([0.1, 0.55, 1.0, 1.45, 1.9], 4)
    th = rng.uniform(-math.pi, math.pi, 20)
    pts = np.column_stack([rho * np.cos(th), rho * np.sin(th), z])
    u, v = truth.project(pts)
    assert np.all((v > 0) & (v < 162))
    uv = np.column_stack([u, v]) + rng.normal(0.0, 1.0, (20, 2))
    cal = calibrate_cylindrical(pts, uv, 1080, 162)
    assert cal.camera.v0_px == pytest.approx(70.0, abs=2.0)
    assert cal.camera.f_v_px == pytest.approx(160.0, rel=0.03)
    assert cal.camera.height_m == pytest.approx(1.05, abs=0.03)
    assert math.degrees(abs(cal.camera.bearing0_rad + 0.4)) < 0.15
    assert cal.residuals_px.shape == (20, 2)
    assert 0.8 < cal.rms_px < 1.8


@pytest.mark.parametrize(
    ("pts", "uv"),
    [
        (np.array([[1.0, 0.0, 0.0], [2.0, 0.0, 1.0]]), np.zeros((2, 2))),  # too few
        (np.array([[1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 0.0, 1.0]]), np.zeros((3, 2))),  # on the axis
        (np.array([[1.0, 0.0, 0.0], [1.0, 1.0e-16, 0.0], [1.0, 0.0, 0.0]]), np.zeros((3, 2))),  # degenerate
        (np.ones((4, 3)), np.ones((3, 2))),  # shapes disagree
    ],
)
def test_calibration_rejects_bad_input(pts: np.ndarray, uv: np.ndarray) -> None:
    with pytest.raises(CalibrationError):
        calibrate_cylindrical(pts, uv, 1080, 162)


# --------------------------------------------------------------------------------------------------
# Annular (PAL) model
# --------------------------------------------------------------------------------------------------

PAL, PAL_CAM = design_pal()


def test_design_pal_rows_are_linear_perspective_over_the_paper_fov() -> None:
    assert (PAL.image_w, PAL.image_h, PAL.pano_w, PAL.pano_h) == (768, 576, 1080, 162)
    assert PAL_CAM.row_from_elevation(math.radians(20.0)) == pytest.approx(-0.5)
    assert PAL_CAM.row_from_elevation(math.radians(-15.0)) == pytest.approx(161.5)
    assert PAL_CAM.f_v_px == pytest.approx(256.36, abs=0.01)
    inner, outer = PAL.radius_range_px
    assert 0 < inner < outer
    # The ring stays inside the image.
    assert PAL.cx_px - outer >= 0 and PAL.cx_px + outer <= 767
    assert PAL.cy_px - outer >= 0 and PAL.cy_px + outer <= 575
    # The maximum perimeter is ~1800 px as in the paper (0.2 deg/px).
    assert 1700 < 2 * math.pi * outer < 1810


def test_design_pal_has_a_genuine_second_order_distortion() -> None:
    """Equal elevation steps land at unequal radius steps, and no straight line fits r(v)."""
    assert PAL.a2 != 0.0
    v = np.linspace(-0.5, 161.5, 50)
    r = PAL.a0 + PAL.a1 * v + PAL.a2 * v * v
    line = np.polyval(np.polyfit(v, r, 1), v)
    assert np.max(np.abs(r - line)) > 3.0  # px: visibly bent (paper's unequal bars, Fig. 1c)


@pytest.mark.parametrize("direction", [1, -1])
@pytest.mark.parametrize("psi0", [0.0, 2.0])
def test_annular_point_round_trip(direction: int, psi0: float) -> None:
    m = AnnularModel(768, 576, 380.0, 290.0, PAL.a0, PAL.a1, PAL.a2, 1080, 162, psi0_rad=psi0, direction=direction)
    rng = np.random.default_rng(3)
    u, v = rng.uniform(0, 1080, 500), rng.uniform(-0.5, 161.5, 500)
    x, y = m.annular_from_pano(u, v)
    u2, v2 = m.pano_from_annular(x, y)
    du = (u2 - u + 540) % 1080 - 540
    assert np.max(np.abs(du)) < 1e-6 and np.max(np.abs(v2 - v)) < 1e-6


def _bilinear(img: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    out = cv2.remap(img, x.astype(np.float32)[None], y.astype(np.float32)[None], cv2.INTER_LINEAR)
    return np.asarray(out[0], dtype=np.float64)


def test_warp_then_unwarp_maps_return_a_point_within_half_a_pixel() -> None:
    """Through the discrete maps: a panorama point goes to the annular image (unwarp map) and back (warp map)."""
    map_ux, map_uy = PAL.unwarp_maps()
    map_wx, map_wy = PAL.warp_maps()
    assert map_ux.shape == (162, 1080) and map_wx.shape == (576, 768)
    assert map_ux.dtype == np.float32 and map_wy.dtype == np.float32
    rng = np.random.default_rng(4)
    u, v = rng.uniform(1, 1078, 400), rng.uniform(1, 160, 400)
    x, y = _bilinear(map_ux, u, v), _bilinear(map_uy, u, v)
    u2, v2 = _bilinear(map_wx, x, y), _bilinear(map_wy, x, y)
    assert np.max(np.hypot(u2 - u, v2 - v)) < 0.5


def test_warp_maps_mark_outside_the_ring() -> None:
    map_x, map_y = PAL.warp_maps()
    assert map_x[int(PAL.cy_px), int(PAL.cx_px)] == -1 and map_y[0, 0] == -1
    inner, outer = PAL.radius_range_px
    r_mid = (inner + outer) / 2
    assert map_x[round(PAL.cy_px), round(PAL.cx_px + r_mid)] >= 0


def test_image_warp_then_unwarp_keeps_a_vertical_line_in_its_column() -> None:
    pano = np.full((162, 1080), 20, np.uint8)
    pano[:, 300] = 250
    pano[:, 1079] = 250  # at the seam too
    wx, wy = PAL.warp_maps()
    padded = np.concatenate([pano, pano[:, :1]], axis=1)
    annular = cv2.remap(padded, wx, wy, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    ux, uy = PAL.unwarp_maps()
    back = cv2.remap(annular, ux, uy, cv2.INTER_LINEAR).astype(np.float64)
    rows = back[5:157]
    assert np.all(np.abs(np.argmax(rows[:, 200:400], axis=1) + 200 - 300) <= 1)
    seam = np.concatenate([rows[:, -20:], rows[:, :20]], axis=1)
    assert np.all(np.abs(np.argmax(seam, axis=1) - 19) <= 1)
    # Sub-pixel: the intensity-weighted column of the line stays within 0.5 px.
    win = rows[:, 295:306] - 20
    centroid = (win * np.arange(295, 306)).sum(axis=1) / win.sum(axis=1)
    assert np.max(np.abs(centroid - 300)) < 0.5


@pytest.mark.parametrize("a2", [0.02, -0.02])
def test_annular_rejects_non_monotonic_radius(a2: float) -> None:
    with pytest.raises(ConfigError, match="monotonic"):
        AnnularModel(768, 576, 384, 288, 200.0, -1.0 if a2 > 0 else 1.0, a2, 1080, 162)


def test_center_from_two_exact_lines() -> None:
    cx, cy = center_from_lines([np.array([[10.0, 10.0], [20.0, 20.0]]), np.array([[0.0, 30.0], [30.0, 0.0]])])
    assert (cx, cy) == (pytest.approx(15.0), pytest.approx(15.0))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_center_from_noisy_vertical_lines(seed: int) -> None:
    """Five imaged vertical lines (spread round the ring, 0.5 px noise) locate the centre within 0.75 px.

    (Median error over many seeds ~0.27 px, 99th percentile ~0.7 px.)
    """
    rng = np.random.default_rng(seed)
    lines = []
    for psi in np.arange(5) * 2 * np.pi / 5 + rng.uniform(0, 1.0, 5):
        x, y = PAL.annular_from_pano(np.full(30, psi * 1080 / (2 * np.pi)), np.linspace(0, 161, 30))
        lines.append(np.column_stack([x, y]) + rng.normal(0, 0.5, (30, 2)))
    cx, cy = center_from_lines(lines)
    assert math.hypot(cx - PAL.cx_px, cy - PAL.cy_px) < 0.5


@pytest.mark.parametrize(
    "lines",
    [
        [np.array([[0.0, 0.0], [1.0, 1.0]])],
        [np.array([[0.0, 0.0], [1.0, 0.0]]), np.array([[0.0, 5.0], [1.0, 5.0]])],
        [np.array([[0.0, 0.0], [0.0, 0.0]]), np.array([[0.0, 5.0], [1.0, 5.0]])],
    ],
)
def test_center_from_lines_rejects_degenerate(lines: list[np.ndarray]) -> None:
    with pytest.raises(CalibrationError):
        center_from_lines(lines)


def test_fit_radial_polynomial_recovers_the_lens() -> None:
    """Step 2: 3 exact pairs give the polynomial; 12 noisy pairs (0.3 px) give r(v) within 0.5 px everywhere.

    (Median worst-row error over many seeds ~0.24 px.)
    """
    v = np.array([0.0, 80.0, 161.0])
    r = PAL.a0 + PAL.a1 * v + PAL.a2 * v * v
    assert fit_radial_polynomial(v, r) == pytest.approx((PAL.a0, PAL.a1, PAL.a2), rel=1e-9)
    rng = np.random.default_rng(0)
    v = np.linspace(0, 161, 12)
    r = PAL.a0 + PAL.a1 * v + PAL.a2 * v * v + rng.normal(0, 0.3, 12)
    a0, a1, a2 = fit_radial_polynomial(v, r)
    vv = np.linspace(0, 161, 100)
    err = (a0 + a1 * vv + a2 * vv**2) - (PAL.a0 + PAL.a1 * vv + PAL.a2 * vv**2)
    assert np.max(np.abs(err)) < 0.5


@pytest.mark.parametrize(
    ("v", "r"), [([1.0, 2.0], [3.0, 4.0]), ([1.0, 1.0, 1.0], [2.0, 2.0, 2.0]), ([1, 2, 3], [1, 2])]
)
def test_fit_radial_polynomial_rejects_bad_input(v: list[float], r: list[float]) -> None:
    with pytest.raises(CalibrationError):
        fit_radial_polynomial(v, r)


# --------------------------------------------------------------------------------------------------
# Pinhole and PTZ
# --------------------------------------------------------------------------------------------------

RVEC = np.array([1.9, -0.4, 0.3])
K = np.array([[1100.0, 0.0, 960.0], [0.0, 1080.0, 540.0], [0.0, 0.0, 1.0]])
R_WC = rotation_from_rvec(RVEC)
T_M = np.array([0.4, 1.2, 9.0])


def _pin(dist: list[float]) -> PinholeCamera:
    return PinholeCamera(k=K, dist=np.array(dist), r=R_WC, t=T_M, width_px=1920, height_px=1080)


def test_rodrigues_matches_opencv() -> None:
    assert np.allclose(rotation_from_rvec(RVEC), cv2.Rodrigues(RVEC)[0], atol=1e-12)


DISTS = [[], [-0.2, 0.05, 0.001, -0.0005], [-0.2, 0.05, 0.001, -0.0005, 0.01], [0.1, 0.01, 0, 0, 0, 0.2, 0.02, 0.001]]


@pytest.mark.parametrize("dist", DISTS)
def test_pinhole_projection_matches_opencv(dist: list[float]) -> None:
    pts = np.random.default_rng(6).uniform([-3, -3, 0], [3, 3, 2], (50, 3))
    cam = _pin(dist)
    uv, in_front = cam.project(pts)
    ref = cv2.projectPoints(pts, RVEC, T_M, K, np.array(dist) if dist else None)[0].reshape(-1, 2)
    assert np.all(in_front)
    assert np.allclose(uv, ref, atol=1e-6)


@pytest.mark.parametrize("dist", DISTS)
def test_pinhole_ray_round_trip(dist: list[float]) -> None:
    cam = _pin(dist)
    pts = np.random.default_rng(7).uniform([-3, -3, 0], [3, 3, 2], (50, 3))
    uv, _ = cam.project(pts)
    rays = cam.ray_world(uv)
    expect = pts - cam.center_world
    expect /= np.linalg.norm(expect, axis=1, keepdims=True)
    assert np.allclose(rays, expect, atol=1e-8)
    az, el = cam.bearing_elevation(uv)
    assert np.allclose(az, np.arctan2(expect[:, 1], expect[:, 0]), atol=1e-8)
    assert np.allclose(el, np.arcsin(expect[:, 2]), atol=1e-8)
    und = cam.undistort_points(uv)
    ideal, _ = _pin([]).project(pts)
    assert np.allclose(und, ideal, atol=1e-5)


def test_pinhole_behind_camera_flagged() -> None:
    cam = _pin([])
    behind = cam.center_world - 2.0 * (R_WC.T @ np.array([0.0, 0.0, 1.0]))
    _, in_front = cam.project(behind[None])
    assert not in_front[0]


def test_pinhole_from_calibration_forms_agree_and_model_round_trips() -> None:
    base = {"model": "pinhole", "image_size": [1920, 1080], "K": K.tolist(), "dist": [], "t": T_M.tolist()}
    a = PinholeCamera.from_calibration({**base, "R": R_WC.tolist()}, "a.json")
    b = PinholeCamera.from_calibration({**base, "rvec": RVEC.tolist()}, "b.json")
    p = K @ np.column_stack([R_WC, T_M])
    c = PinholeCamera.from_calibration({"model": "pinhole", "image_size": [1920, 1080], "P": (-2.5 * p).tolist()}, "c")
    for cam in (b, c):
        assert np.allclose(cam.k, a.k, atol=1e-9)
        assert np.allclose(cam.r, a.r, atol=1e-9)
        assert np.allclose(cam.t, a.t, atol=1e-9)
    d = PinholeCamera.from_model(_pin(DISTS[2]).to_model())
    assert np.array_equal(d.dist, DISTS[2]) and np.allclose(d.r, R_WC) and np.allclose(d.center_world, a.center_world)


@pytest.mark.parametrize(
    ("patch", "match"),
    [
        ({"model": "fisheye"}, "model"),
        ({"image_size": [1920]}, "image_size"),
        ({"image_size": [1920.5, 1080]}, "image_size"),
        ({"K": [[1, 0], [0, 1]]}, "K"),
        ({"K": "abc"}, "K"),
        ({"R": np.eye(3).tolist()[:2]}, "R"),
        ({"R": (2 * np.eye(3)).tolist()}, "rotation"),
        ({"t": [0, 0]}, "t"),
        ({"t": [0, float("nan"), 0]}, "finite"),
        ({"dist": [0.1, 0.2, 0.3]}, "dist"),
        ({"K": [[-5, 0, 1], [0, 5, 1], [0, 0, 1]]}, "fx"),
        ({"P": [[0.0] * 4] * 3}, "singular"),
    ],
)
def test_pinhole_from_calibration_rejects_bad_input_naming_the_source(patch: dict[str, object], match: str) -> None:
    good = {"model": "pinhole", "image_size": [1920, 1080], "K": K.tolist(), "dist": [], "R": R_WC.tolist()}
    good["t"] = T_M.tolist()
    with pytest.raises(ConfigError, match=match) as info:
        PinholeCamera.from_calibration({**good, **patch}, "cams/c7.json")
    assert str(info.value).startswith("cams/c7.json:")


def test_pinhole_from_calibration_rejects_non_object() -> None:
    with pytest.raises(ConfigError, match=r"^x\.json: expected a JSON object"):
        PinholeCamera.from_calibration([1, 2], "x.json")  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("pan_deg", "tilt_deg", "zoom"), [(0.0, 0.0, 1.0), (135.0, -20.0, 1.0), (-60.0, 10.0, 3.0), (179.0, 35.0, 8.0)]
)
def test_ptz_axis_and_pixels(pan_deg: float, tilt_deg: float, zoom: float) -> None:
    head = PtzCamera(2.0, -1.0, 2.5, 1280, 720, math.radians(60.0))
    cam = head.with_state(math.radians(pan_deg), math.radians(tilt_deg), zoom).pinhole()
    assert np.allclose(cam.center_world, [2.0, -1.0, 2.5])
    az, el = cam.bearing_elevation(np.array([[639.5, 359.5]]))
    assert math.degrees(az[0]) == pytest.approx(pan_deg, abs=1e-9)
    assert math.degrees(el[0]) == pytest.approx(tilt_deg, abs=1e-9)
    # Notes section 5: azimuth = pan - atan2(right, fwd), elevation = atan2(up, hypot(right, fwd)).
    f = zoom * 640 / math.tan(math.radians(30.0))
    uv = np.array([[1000.0, 100.0], [50.0, 700.0]])
    x, y = (uv[:, 0] - 639.5) / f, (uv[:, 1] - 359.5) / f
    t = math.radians(tilt_deg)
    right, fwd, up = x, y * math.sin(t) + math.cos(t), -y * math.cos(t) + math.sin(t)
    az, el = cam.bearing_elevation(uv)
    assert np.allclose(az, np.angle(np.exp(1j * (math.radians(pan_deg) - np.arctan2(right, fwd)))), atol=1e-9)
    assert np.allclose(el, np.arctan2(up, np.hypot(right, fwd)), atol=1e-9)
    # World point -> pixel -> ray round trip.
    target = np.array([[2.0 + 5 * math.cos(az[0]), -1.0 + 5 * math.sin(az[0]), 2.5 + 5 * math.tan(el[0])]])
    uv_back, in_front = cam.project(target)
    assert in_front[0] and np.allclose(uv_back[0], uv[0], atol=1e-6)


def test_ptz_zoom_narrows_the_view_and_validates() -> None:
    head = PtzCamera(0.0, 0.0, 2.0, 1280, 720, math.radians(60.0))
    edge = np.array([[1279.5, 359.5]])
    a1, _ = head.pinhole().bearing_elevation(edge)
    a4, _ = head.with_state(0.0, 0.0, 4.0).pinhole().bearing_elevation(edge)
    assert math.degrees(-a1[0]) == pytest.approx(30.0, abs=0.05)
    assert math.tan(-a4[0]) == pytest.approx(math.tan(-a1[0]) / 4, rel=1e-9)
    with pytest.raises(ConfigError):
        head.with_state(0.0, 0.0, 0.0)
    with pytest.raises(ConfigError):
        PtzCamera(0.0, 0.0, 2.0, 1280, 720, math.radians(190.0))


@pytest.mark.parametrize("seed", [0, 1])
def test_steps_1_and_2_recover_the_lens_from_noisy_image_points(seed: int) -> None:
    """Centre from 8 imaged vertical lines, then the radial polynomial from marks at known elevations.

    Marks every 2.5 deg of elevation on 8 vertical poles, imaged with 0.3 px noise. The
    rebuilt model maps every panorama pixel within 0.6 px of the true lens (worst pixel:
    median 0.26 px, max 0.50 px over 100 seeds).
    """
    rng = np.random.default_rng(seed)
    elevations = np.radians(np.arange(-15.0, 20.1, 2.5))
    rows_true = PAL_CAM.row_from_elevation(elevations)
    cols = np.arange(8) * 135.0 + rng.uniform(0, 60)
    marks = [
        np.column_stack(PAL.annular_from_pano(np.full(rows_true.size, u), rows_true))
        + rng.normal(0, 0.3, (rows_true.size, 2))
        for u in cols
    ]
    cx, cy = center_from_lines(marks)
    radii = np.concatenate([np.hypot(m[:, 0] - cx, m[:, 1] - cy) for m in marks])
    a0, a1, a2 = fit_radial_polynomial(np.tile(rows_true, len(marks)), radii)
    rebuilt = AnnularModel(768, 576, cx, cy, a0, a1, a2, 1080, 162)
    vv, uu = np.mgrid[0:162:7, 0:1080:13].astype(float)
    x0, y0 = PAL.annular_from_pano(uu, vv)
    x1, y1 = rebuilt.annular_from_pano(uu, vv)
    assert np.max(np.hypot(x1 - x0, y1 - y0)) < 0.6
