"""Pinhole and PTZ cameras: projection against OpenCV, ray round trips, calibration forms, PTZ zoom."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from common.errors import ConfigError
from common.pinhole import PinholeCamera, PtzCamera, rotation_from_rvec

RVEC = np.array([1.9, -0.4, 0.3])
K = np.array([[1100.0, 0.0, 960.0], [0.0, 1080.0, 540.0], [0.0, 0.0, 1.0]])


R_WC = rotation_from_rvec(RVEC)
T_M = np.array([0.4, 1.2, 9.0])


def _pin(dist: list[float]) -> PinholeCamera:
    return PinholeCamera(k=K, dist=np.array(dist), r=R_WC, t=T_M, width_px=1920, height_px=1080)


def test_rodrigues_matches_opencv() -> None:
    assert np.allclose(rotation_from_rvec(RVEC), cv2.Rodrigues(RVEC)[0], atol=1e-12)


DISTS = [
    [],
    [-0.2, 0.05, 0.001, -0.0005],
    [-0.2, 0.05, 0.001, -0.0005, 0.01],
    [0.1, 0.01, 0, 0, 0, 0.2, 0.02, 0.001],
    [-0.2, 0.05, 0.001, -0.0005, 0.01, 0.02, 0.001, 0.0005, 0.002, -0.001, 0.001, 0.0005],  # thin prism too
]


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
