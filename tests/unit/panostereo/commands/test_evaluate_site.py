"""``panostereo evaluate-site``: JSON on stdout, the tracks CSV, and a missing site refused without a traceback."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from panostereo.datasets.mot import import_mot
from tests.support import REPO


def test_the_cli_prints_json_and_writes_the_tracks(made: Path, tmp_path: Path) -> None:
    site = import_mot(made, tmp_path / "site", fps=5.0).site
    csv = tmp_path / "tracks.csv"
    cmd = [sys.executable, "-m", "panostereo", "evaluate-site", str(site), "--json", "--tracks-csv", str(csv)]
    out = subprocess.run(cmd, capture_output=True, text=True, check=True, cwd=REPO)
    report = json.loads(out.stdout)
    assert report["scores"][0]["mota"] >= 0.9 and report["tracks_csv"]["rows"] > 60
    rows = csv.read_text().splitlines()
    assert rows[0] == "frame,id,x_m,y_m" and rows[1].startswith("1,")
    bad = subprocess.run(
        [sys.executable, "-m", "panostereo", "evaluate-site", str(tmp_path / "nope.toml")],
        capture_output=True,
        text=True,
        cwd=REPO,
        check=False,
    )
    assert bad.returncode != 0 and "nope.toml" in bad.stderr and "Traceback" not in bad.stderr


def test_a_wrong_frame_rate_is_warned_about_and_the_run_is_drawn(
    made: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from panostereo.cli import main

    site = import_mot(made, tmp_path / "site", fps=50.0).site  # the set is 5 fps: people would run at 5 m/s
    png = tmp_path / "top.png"
    assert main(["evaluate-site", str(site), "--plot", str(png)]) == 0
    out, err = capsys.readouterr()
    assert "WARNING: at 50 fps the ground truth" in err and f"plot: {png}" in out
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
