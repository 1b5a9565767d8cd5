"""Calibration converters (common.calib_formats, ``panostereo calib convert``): Tsai, OpenCV YAML, P matrix.

The Tsai test writes a PETS-style XML itself (the PETS XML files are not in ../shared) and checks the
converted JSON's floor points against an independent, exact Tsai back-projection written here; the
XML is built from ../shared's own view001.json (its K, R, t, and the Tsai kappa1 its fitted
distortion stands for), so the conversion must also give that file back.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from common.calib_formats import from_opencv_file, from_p_matrix, from_tsai_xml, tsai_rotation
from common.errors import ConfigError
from common.pinhole import PinholeCamera
from panostereo.cli import main as panostereo_main
from tests.support import REPO, skip_or_fail

VIEW001 = REPO.parent / "shared" / "datasets" / "pets2009_s2l1" / "calib" / "view001.json"
FOCAL_MM = 5.6


def _rational(dist: list[float], r2: float) -> float:
    d = list(dist) + [0.0] * (8 - len(dist))
    return (1 + r2 * (d[0] + r2 * (d[1] + r2 * d[4]))) / (1 + r2 * (d[5] + r2 * (d[6] + r2 * d[7])))


def _tsai_from_json(cal: dict) -> dict[str, float]:
    """Tsai parameters that a pinhole JSON stands for (kappa1 read off its distortion at one radius)."""
    k, r = np.asarray(cal["K"]), np.asarray(cal["R"])
    ru = 0.25  # normalised undistorted radius inside the image
    rd = ru * _rational(cal["dist"], ru * ru)
    kappa = (ru / rd - 1.0) / (rd * rd)  # Tsai: ru = rd (1 + kappa rd^2), normalised units
    return {
        "width": cal["image_size"][0], "height": cal["image_size"][1],
        "dpx": FOCAL_MM / k[0, 0], "dpy": FOCAL_MM / k[1, 1], "focal": FOCAL_MM, "sx": 1.0,
        "cx": k[0, 2], "cy": k[1, 2], "kappa1": kappa / FOCAL_MM**2,
        "rx": math.atan2(r[2, 1], r[2, 2]), "ry": -math.asin(r[2, 0]), "rz": math.atan2(r[1, 0], r[0, 0]),
        "tx": cal["t"][0] * 1000.0, "ty": cal["t"][1] * 1000.0, "tz": cal["t"][2] * 1000.0,
    }  # fmt: skip


def _xml(p: dict[str, float]) -> str:
    g = " ".join(f'{k}="{float(p[k])!r}"' for k in ("width", "height", "dpx", "dpy"))
    i = " ".join(f'{k}="{float(p[k])!r}"' for k in ("focal", "kappa1", "cx", "cy", "sx"))
    e = " ".join(f'{k}="{float(p[k])!r}"' for k in ("tx", "ty", "tz", "rx", "ry", "rz"))
    geometry = f'<Geometry {g} ncx="768" nfx="768" dx="1" dy="1"/>'
    return f'<Camera name="View_001">{geometry}<Intrinsic {i}/><Extrinsic {e}/></Camera>'


def _tsai_floor(p: dict[str, float], uv: np.ndarray) -> np.ndarray:
    """Exact Tsai back-projection of pixels onto the floor z = 0, metres (independent of the converter)."""
    xd = (uv[:, 0] - p["cx"]) * p["dpx"] / p["sx"]  # sensor mm
    yd = (uv[:, 1] - p["cy"]) * p["dpy"]
    f = 1.0 + p["kappa1"] * (xd**2 + yd**2)
    xu, yu = xd * f, yd * f
    c, s = np.cos, np.sin
    rx, ry, rz = p["rx"], p["ry"], p["rz"]
    r = (
        np.array([[c(rz), -s(rz), 0], [s(rz), c(rz), 0], [0, 0, 1]])
        @ np.array([[c(ry), 0, s(ry)], [0, 1, 0], [-s(ry), 0, c(ry)]])
        @ np.array([[1, 0, 0], [0, c(rx), -s(rx)], [0, s(rx), c(rx)]])
    )
    d = np.stack([xu, yu, np.full_like(xu, p["focal"])], 1) @ r  # camera -> world directions
    centre = -r.T @ np.array([p["tx"], p["ty"], p["tz"]])
    return (centre + (-centre[2] / d[:, 2])[:, None] * d)[:, :2] / 1000.0


def _floor(cam: PinholeCamera, uv: np.ndarray) -> np.ndarray:
    ray = cam.ray_world(uv)
    c = cam.center_world
    return c[:2] + (-c[2] / ray[:, 2])[:, None] * ray[:, :2]


def _grid(w: int, h: int) -> np.ndarray:
    u, v = np.meshgrid(np.linspace(0, w - 1, 24), np.linspace(h * 0.3, h - 1, 16))
    return np.column_stack([u.ravel(), v.ravel()])


@pytest.fixture(scope="module")
def view001() -> dict:
    if not VIEW001.is_file():
        skip_or_fail(f"PETS calibration not found at {VIEW001}")
    return json.loads(VIEW001.read_text())


def test_tsai_xml_converts_to_floor_points_of_the_exact_tsai_model(view001: dict, tmp_path: Path) -> None:
    p = _tsai_from_json(view001)
    cal = from_tsai_xml(_xml(p))
    cam = PinholeCamera.from_calibration(cal, "converted")
    uv = _grid(cal["image_size"][0], cal["image_size"][1])
    exact = _tsai_floor(p, uv)
    near = np.hypot(*(exact - cam.center_world[:2]).T) < 80.0  # not the rows by the horizon
    assert near.sum() > 200
    assert np.abs(_floor(cam, uv[near]) - exact[near]).max() < 0.005  # metres
    # The same camera as ../shared's view001.json (converted there by another implementation).
    np.testing.assert_allclose(cal["K"], view001["K"], rtol=1e-9)
    np.testing.assert_allclose(cal["R"], view001["R"], atol=1e-12)
    np.testing.assert_allclose(cal["t"], view001["t"], atol=1e-9)
    theirs = PinholeCamera.from_calibration(view001, "view001.json")
    assert np.abs(_floor(theirs, uv[near]) - exact[near]).max() < 0.01
    # Rotation order: Rz Ry Rx, not Rx Ry Rz.
    assert not np.allclose(tsai_rotation(0.3, 0.2, 0.1), tsai_rotation(0.1, 0.2, 0.3))


def test_tsai_convert_command_and_its_errors(view001: dict, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    xml = tmp_path / "View_001.xml"
    xml.write_text(_xml(_tsai_from_json(view001)))
    out = tmp_path / "view001.json"
    assert panostereo_main(["calib", "convert", "--from", "tsai", str(xml), "--out", str(out)]) == 0
    cam = PinholeCamera.from_calibration(json.loads(out.read_text()), "out")
    np.testing.assert_allclose(cam.center_world, [-28.9, -19.5, 7.07], atol=0.1)  # ABOUT.md's view001
    bad = tmp_path / "bad.xml"
    bad.write_text(xml.read_text().replace(' kappa1="', ' kappaX="'))
    assert panostereo_main(["calib", "convert", "--from", "tsai", str(bad), "--out", str(out)]) == 1
    assert "kappa1" in capsys.readouterr().err


def test_opencv_yaml_in_mm_gives_the_same_projection(tmp_path: Path) -> None:
    k = np.array([[800.0, 0, 320.0], [0, 810.0, 240.0], [0, 0, 1]])
    dist = np.array([-0.2, 0.05, 0.001, -0.002, 0.0])
    rvec = np.array([[1.9], [0.3], [-0.2]])
    tvec_mm = np.array([[150.0], [900.0], [6000.0]])
    path = tmp_path / "cam.yml"
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    fs.write("image_width", 640)
    fs.write("image_height", 480)
    fs.write("camera_matrix", k)
    fs.write("distortion_coefficients", dist)
    fs.write("rvec", rvec)
    fs.write("tvec", tvec_mm)
    fs.release()
    cal = from_opencv_file(path, units_m=0.001)
    cam = PinholeCamera.from_calibration(cal, "yaml")
    world_m = np.array([[0.5, 1.0, 0.0], [2.0, -1.0, 1.7], [-1.0, 0.3, 0.4]])
    ours, _ = cam.project(world_m)
    ref, _ = cv2.projectPoints(world_m * 1000.0, rvec, tvec_mm, k, dist)
    np.testing.assert_allclose(ours, ref.reshape(-1, 2), atol=1e-6)
    with pytest.raises(ConfigError, match="camera_matrix"):
        empty = tmp_path / "empty.yml"
        fs = cv2.FileStorage(str(empty), cv2.FILE_STORAGE_WRITE)
        fs.write("image_width", 640)
        fs.release()
        from_opencv_file(empty)


def test_p_matrix_is_decomposed_into_k_r_t() -> None:
    k = np.array([[1000.0, 0, 384.0], [0, 1000.0, 288.0], [0, 0, 1]])
    r = tsai_rotation(-1.9, 0.2, 0.7)
    t = np.array([0.5, -1.0, 20.0])
    p = k @ np.column_stack([r, t])
    cal = from_p_matrix(" ".join(repr(float(x)) for x in (3.0 * p).ravel()), (768, 576))
    np.testing.assert_allclose(cal["K"], k, atol=1e-6)
    np.testing.assert_allclose(cal["R"], r, atol=1e-9)
    np.testing.assert_allclose(cal["t"], t, atol=1e-6)
    with pytest.raises(ConfigError, match="12 numbers"):
        from_p_matrix("1 2 3", (768, 576))
