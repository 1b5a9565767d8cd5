"""`panostereo calib convert`: a small P-matrix file becomes the pinhole JSON of the same camera; bad input is
refused with exit code 1 and a message naming what is wrong."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from common.calib_formats import tsai_rotation
from common.pinhole import PinholeCamera
from panostereo.cli import main

K = np.array([[900.0, 0.0, 320.0], [0.0, 900.0, 240.0], [0.0, 0.0, 1.0]])
R = tsai_rotation(-2.0, 0.1, 0.4)
CENTRE_M = np.array([1.5, -2.0, 3.2])


def _p_file(tmp_path: Path, units_m: float = 1.0, sep: str = " ") -> Path:
    t = -R @ (CENTRE_M / units_m)
    p = 2.5 * K @ np.column_stack([R, t])  # any scale: P is homogeneous
    path = tmp_path / "P.txt"
    path.write_text("\n".join(sep.join(repr(float(v)) for v in row) for row in p) + "\n")
    return path


@pytest.mark.parametrize(("units", "units_m", "sep"), [(None, 1.0, " "), ("mm", 0.001, ", "), ("cm", 0.01, " ")])
def test_a_p_matrix_converts_to_the_same_camera_in_metres(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], units: str | None, units_m: float, sep: str
) -> None:
    out = tmp_path / "cam.json"
    args = ["calib", "convert", str(_p_file(tmp_path, units_m, sep)), "--from", "p-matrix"]
    args += ["--image-size", "640", "480", "--out", str(out)] + (["--units", units] if units else [])
    assert main(args) == 0
    cal = json.loads(out.read_text())
    assert cal["model"] == "pinhole" and cal["image_size"] == [640, 480]
    cam = PinholeCamera.from_calibration(cal, "cam.json")
    assert cam.center_world == pytest.approx(CENTRE_M, abs=1e-6)
    world = CENTRE_M + 6.0 * R[2] + np.array([[0.0, 0.0, 0.0], [0.5, -0.3, 0.4]])  # in front of the camera
    expected = (K @ (R @ (world - CENTRE_M).T)).T
    uv, _ = cam.project(world)
    assert uv == pytest.approx(expected[:, :2] / expected[:, 2:], abs=1e-6)
    assert "camera at (1.500, -2.000, 3.200) m" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("extra", "text", "message"),
    [
        (["--image-size", "640", "480"], "1 2 3 4 5 6 7 8 9 10 11", "12 numbers"),
        (["--image-size", "640", "480"], "1 2 3 4 5 6 7 8 9 10 11 x", "12 numbers"),
        (["--image-size", "640", "480"], "0 0 0 0 0 0 0 0 0 0 0 0", "P.txt"),  # singular
        ([], None, "needs --image-size"),
        (["--image-size", "0", "480"], None, "--image-size"),
    ],
)
def test_a_bad_p_matrix_or_missing_size_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], extra: list[str], text: str | None, message: str
) -> None:
    src = _p_file(tmp_path)
    if text is not None:
        src.write_text(text)
    out = tmp_path / "cam.json"
    assert main(["calib", "convert", str(src), "--from", "p-matrix", "--out", str(out), *extra]) == 1
    assert message in capsys.readouterr().err
    assert not out.exists()


def test_an_unreadable_input_and_tsai_in_metres_are_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = str(tmp_path / "c.json")
    assert main(["calib", "convert", str(tmp_path / "none.txt"), "--from", "p-matrix", "--out", out]) == 1
    assert "none.txt" in capsys.readouterr().err
    xml = tmp_path / "v.xml"
    xml.write_text("<Camera/>")
    assert main(["calib", "convert", str(xml), "--from", "tsai", "--units", "m", "--out", out]) == 1
    assert "Tsai calibrations are in mm" in capsys.readouterr().err


def test_a_two_file_calibration_as_wildtrack_keeps_it_converts_like_its_importer(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import cv2

    from panostereo.datasets.wildtrack import GridSpec, calibration

    rvec, _ = cv2.Rodrigues(R)
    tvec_cm = -R @ CENTRE_M / 0.01
    root = tmp_path / "wt"
    (root / "calibrations" / "intrinsic_zero").mkdir(parents=True)
    (root / "calibrations" / "extrinsic").mkdir(parents=True)
    intr = root / "calibrations" / "intrinsic_zero" / "intr_Cam1.xml"
    extr = root / "calibrations" / "extrinsic" / "extr_Cam1.xml"
    k_text = " ".join(repr(float(v)) for v in K.ravel())
    intr.write_text('<?xml version="1.0"?>\n<opencv_storage>\n<camera_matrix type_id="opencv-matrix">\n<rows>3</rows>'
                    f"<cols>3</cols><dt>d</dt><data>{k_text}</data></camera_matrix>\n</opencv_storage>\n")  # fmt: skip
    extr.write_text(f'<?xml version="1.0"?>\n<opencv_storage>\n<rvec>{" ".join(map(repr, rvec.ravel().tolist()))}'
                    f"</rvec>\n<tvec>{' '.join(map(repr, tvec_cm.tolist()))}</tvec>\n</opencv_storage>\n")  # fmt: skip
    out = tmp_path / "cam.json"
    args = ["calib", "convert", str(intr), "--from", "opencv-yaml", "--extrinsic", str(extr), "--units", "cm"]
    assert main([*args, "--image-size", "1920", "1080", "--out", str(out)]) == 0
    got = json.loads(out.read_text())
    want = calibration(root, "Cam1", GridSpec(), (1920, 1080))
    for key in ("K", "R", "t", "image_size"):
        assert np.asarray(got[key]) == pytest.approx(np.asarray(want[key]), abs=1e-9)
    assert PinholeCamera.from_calibration(got, "cam.json").center_world == pytest.approx(CENTRE_M, abs=1e-6)
    # Alone, the intrinsic file has no pose: the message says which flag brings it.
    assert main(["calib", "convert", str(intr), "--from", "opencv-yaml", "--out", str(out)]) == 1
    assert "--extrinsic FILE" in capsys.readouterr().err
