"""`panostereo plan`: numbers, JSON shape, the Fig. 4 PNG and input errors."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

from panostereo.cli import main

KEYS = {
    "baseline_m",
    "phi1_deg",
    "o2_positions_m",
    "normalised_error",
    "error_m",
    "eq5_bound_m",
    "eq6_fixed_baseline_m",
}


def _plan_json(capsys: pytest.CaptureFixture[str], *extra: str) -> dict[str, Any]:
    assert main(["plan", "--distance", "6", "--radius", "0.18", "--json", *extra]) == 0
    out = capsys.readouterr().out
    assert out.count("\n") == 1  # exactly one JSON object on one line
    return dict(json.loads(out))


def test_plan_json_has_exactly_the_documented_numbers(capsys: pytest.CaptureFixture[str]) -> None:
    res = _plan_json(capsys)
    assert set(res) == KEYS
    assert res["baseline_m"] == pytest.approx(2.1655, abs=0.005)
    assert res["phi1_deg"] == pytest.approx(59.45, abs=0.1)
    assert res["normalised_error"] == pytest.approx(11.098, abs=0.02)
    (xa, ya), (xb, yb) = res["o2_positions_m"]
    assert (xa, xb) == (pytest.approx(1.1007, abs=0.005), pytest.approx(1.1007, abs=0.005))
    assert ya == pytest.approx(1.8649, abs=0.005) and yb == -ya
    dphi = math.radians(0.2)
    assert res["error_m"] == pytest.approx(11.098 * 6 * dphi, rel=2e-3)  # notes: 23.2 cm
    assert res["eq5_bound_m"] == pytest.approx(2 * 6 * math.sqrt(6 / 0.18) * dphi, rel=1e-9)
    assert res["eq6_fixed_baseline_m"] == pytest.approx(33.258 * 6 * dphi, rel=1e-4)
    assert res["error_m"] < res["eq5_bound_m"] < res["eq6_fixed_baseline_m"]


@pytest.mark.parametrize("err_deg", [0.1, 0.333, 1.0])
def test_plan_error_scales_with_bearing_error(capsys: pytest.CaptureFixture[str], err_deg: float) -> None:
    res = _plan_json(capsys, "--bearing-error-deg", str(err_deg))
    assert res["error_m"] == pytest.approx(res["normalised_error"] * 6 * math.radians(err_deg), rel=1e-12)
    assert res["baseline_m"] == pytest.approx(2.1655, abs=0.005)


def test_plan_text_output(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["plan", "--distance", "6", "--radius", "0.18"]) == 0
    out = capsys.readouterr().out
    for key in KEYS:
        assert key in out
    assert "2.1655" in out and "59.451" in out and "11.0984" in out


def test_plan_map_png(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "fig4.png"
    res = _plan_json(capsys, "--map", str(path))
    img = cv2.imread(str(path))
    assert img is not None and img.shape[0] > 400 and img.shape[1] > 600
    # A colour map was drawn: many distinct colours, both JET ends (dark blue and dark red) present.
    colours = np.unique(img.reshape(-1, 3), axis=0)
    assert len(colours) > 200
    b, g, r = img[..., 0].astype(int), img[..., 1].astype(int), img[..., 2].astype(int)
    assert np.any((b > 100) & (r < 30) & (g < 30)) and np.any((r > 100) & (b < 30) & (g < 30))
    assert res["baseline_m"] == pytest.approx(2.1655, abs=0.005)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--distance", "0.2", "--radius", "0.18"], "--distance"),
        (["--distance", "6", "--radius", "-1"], "--radius"),
        (["--distance", "6", "--radius", "0.18", "--bearing-error-deg", "0"], "--bearing-error-deg"),
        (["--distance", "nan", "--radius", "0.18"], "--distance"),
    ],
)
def test_plan_rejects_bad_input(capsys: pytest.CaptureFixture[str], args: list[str], message: str) -> None:
    assert main(["plan", *args]) == 1
    err = capsys.readouterr().err
    assert message in err and err.startswith("panostereo plan: error:")


@pytest.mark.parametrize(
    ("name", "message"),
    [("no/such/dir/map.png", "does not exist"), (".", "png"), ("map.jpg", "png"), ("dir.png", "directory")],
)
def test_plan_map_path_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str], name: str, message: str) -> None:
    (tmp_path / "dir.png").mkdir()
    path = tmp_path / name
    assert main(["plan", "--distance", "6", "--radius", "0.18", "--map", str(path)]) == 1
    out, err = capsys.readouterr()
    assert out == ""  # nothing printed when the map cannot be written
    assert err.count("\n") == 1 and err.startswith("panostereo plan: error: --map") and message in err


def test_plan_runs_as_a_module() -> None:
    out = subprocess.run(
        [sys.executable, "-m", "panostereo", "plan", "--distance", "8", "--radius", "0.18", "--json"],
        capture_output=True,
        text=True,
        timeout=60,
        check=True,
    )
    res = json.loads(out.stdout)
    assert res["baseline_m"] == pytest.approx(2.4731, abs=0.005)
    assert res["phi1_deg"] == pytest.approx(63.73, abs=0.1)
