"""The refined site: the same files in the same layout, new calibrations, the rest as it was."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from common.errors import ConfigError
from common.site import load_site
from panostereo.calib.poses import CameraPose
from panostereo.calib.site_out import _pose_table, write_refined_site
from tests.unit.panostereo.calib.synth import true_cameras, write_site_dir


def test_a_pose_table_gets_new_numbers_and_keeps_its_comments() -> None:
    text = (
        '[node]\nid = "p"\n\n[pose]   # on a post\nx_m = 1.0   # measured\ny_m = 2.0\nz_m = 1.1\n\n[[body]]\nid = "q"\n'
    )
    out = _pose_table(text, CameraPose.from_yaw(1.5, 2.5, 1.2, math.radians(95.0)), "p.toml")
    assert "x_m = 1.5000   # measured" in out and "yaw_deg = 95.0000" in out and "[pose]   # on a post" in out
    assert out.index("yaw_deg") < out.index("[[body]]")
    with pytest.raises(ConfigError, match="no \\[pose\\] table"):
        _pose_table('[node]\nid = "p"\n', CameraPose.from_yaw(0, 0, 1, 0), "p.toml")


def test_the_site_is_copied_with_new_calibrations(tmp_path: Path) -> None:
    truth = true_cameras()
    site = load_site(write_site_dir(tmp_path / "site", truth, truth, frames=5, seed=2))
    cam = truth["cam-b"]
    new = CameraPose(np.array(cam.r), cam.center_world + np.array([0.0, 0.3, 0.0]), level=False)
    models = {cid: c.to_model() for cid, c in truth.items()}
    out = write_refined_site(site, {"cam-b": new}, models, tmp_path / "out")
    assert out == (tmp_path / "out" / "site.toml").resolve()
    for rel in ("nodes/cam-a.toml", "nodes/manager.toml", "detections/cam-b.txt", "gt.csv", "calib/cam-a.json"):
        assert (tmp_path / "out" / rel).read_bytes() == (tmp_path / "site" / rel).read_bytes()
    written = json.loads((tmp_path / "out" / "calib" / "cam-b.json").read_text())
    assert (
        np.allclose(written["t"], new.t_m)
        and written["K"] == json.loads((tmp_path / "site" / "calib" / "cam-b.json").read_text())["K"]
    )
    with pytest.raises(ConfigError, match="--out"):
        write_refined_site(site, {}, models, tmp_path / "site")
