"""`panostereo render`: one simulated frame of a site's camera to a PNG (raw and panorama), and its summary."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import pytest

from panostereo.cli import main
from tests.support import REPO

SITES = REPO / "deploy" / "sites"


def test_render_command_writes_the_raw_frame_and_its_panorama(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "sub" / "f.png"
    site = str(SITES / "demo.toml")
    assert main(["render", "--site", site, "--camera", "pano1", "--time", "5", "--out", str(out)]) == 0
    summary = json.loads(capsys.readouterr().out)
    raw, pano = cv2.imread(str(out)), cv2.imread(str(tmp_path / "sub" / "f_pano.png"))
    assert raw.shape == (576, 768, 3) and pano.shape == (162, 1080, 3)
    assert len(summary["people"]) == 4 and {p["id"] for p in summary["platforms"]} == {"pano2", "pano3", "ptz1"}
    assert main(["render", "--site", site, "--camera", "ptz1", "--out", str(tmp_path / "p.png")]) == 0
    assert cv2.imread(str(tmp_path / "p.png")).shape == (480, 640, 3)
    assert main(["render", "--site", site, "--camera", "nope", "--out", str(tmp_path / "n.png")]) == 1
    assert main(["render", "--site", site, "--camera", "pano1", "--out", str(tmp_path / "n.unknown-ext")]) == 1
