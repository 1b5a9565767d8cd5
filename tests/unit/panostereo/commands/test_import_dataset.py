"""`panostereo import mot`: the command's flags reach the importer, its summary names the site written, and a
missing frame rate is refused."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from common.site import load_site
from panostereo.cli import main
from panostereo.datasets.mot import import_mot
from sensor_node.config import DetectionsSource, load_node_config
from tests.unit.panostereo.mot_synth import CAMERAS


def _summary(capsys: pytest.CaptureFixture[str]) -> dict[str, Any]:
    out = capsys.readouterr().out
    body, _, hints = out.partition("\nrun it: ")
    summary: dict[str, Any] = json.loads(body)
    assert f"panostereo demo --site {summary['site']}" in hints  # how to run what was written
    return summary


def test_import_mot_writes_a_runnable_site_and_prints_its_summary(
    made: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "site"
    args = ["import", "mot", str(made), "--out", str(out), "--fps", "5", "--area", "0,0,10,10"]
    assert main([*args, "--min-confidence", "0.4", "--name", "lab"]) == 0
    summary = _summary(capsys)
    assert summary["cameras"] == sorted(CAMERAS) and (summary["frames"], summary["people"]) == (30, 3)
    site = load_site(summary["site"])
    assert Path(summary["site"]) == out / "site.toml" and site.site.name == "lab"
    assert site.dataset is not None and site.dataset.fps == 5.0
    assert site.area is not None and site.area.polygon == [[0, 0], [10, 0], [10, 10], [0, 10]]
    node = load_node_config(site.resolve("nodes/north.toml"))
    assert isinstance(node.source, DetectionsSource) and node.source.min_confidence == 0.4


@pytest.mark.parametrize("area", ["0,0,10", "0,0,a,10", "5,0,1,10"])
def test_a_bad_area_is_one_clear_error(
    made: Path, tmp_path: Path, area: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["import", "mot", str(made), "--out", str(tmp_path / "s"), "--fps", "5", "--area", area]) != 0
    err = capsys.readouterr().err
    assert "area" in err and "Traceback" not in err and len(err.strip().splitlines()) == 1


def test_noise_and_drops_reach_the_importer_with_their_seed(
    made: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    args = ["--fps", "5", "--noise-px", "1.5", "--drop-rate", "0.25", "--seed", "7"]
    assert main(["import", "mot", str(made), "--out", str(tmp_path / "cli"), *args]) == 0
    summary = _summary(capsys)
    direct = import_mot(made, tmp_path / "direct", fps=5.0, noise_px=1.5, drop_rate=0.25, seed=7)
    assert summary["dropped"] == direct.dropped > 0 and summary["boxes"] == direct.boxes
    cam = "north"  # any of the three
    written = (tmp_path / "cli" / "detections" / f"{cam}.txt").read_text()
    assert written == (tmp_path / "direct" / "detections" / f"{cam}.txt").read_text()


def test_import_mot_without_a_frame_rate_is_refused(
    made: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["import", "mot", str(made), "--out", str(tmp_path / "site")]) == 1
    assert "--fps is required" in capsys.readouterr().err
    assert not (tmp_path / "site").exists()
