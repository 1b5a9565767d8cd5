"""The cylindrical virtual camera (Step 3): bearings, elevations, floor distances, its calibration."""

from __future__ import annotations

import math

import numpy as np
import pytest

from common.cylindrical import CylindricalCamera, calibrate_cylindrical
from common.errors import CalibrationError, ConfigError

CAM = CylindricalCamera(width_px=1080, height_px=162, f_v_px=256.0, v0_px=93.0, height_m=1.1)


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
