"""``panostereo import wildtrack`` on the real dataset (passed by path, never copied)."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from common.pinhole import PinholeCamera
from common.site import load_site
from panostereo.datasets.wildtrack import import_wildtrack
from sensor_node.config import DetectionsSource, load_node_config
from tests.support import REPO, skip_or_fail
from user_agent.groundtruth import read_gt_csv

DATASET = REPO.parent / "shared" / "datasets" / "wildtrack"


@pytest.fixture(scope="module")
def dataset() -> Path:
    if not (DATASET / "annotations_positions").is_dir():
        skip_or_fail(f"Wildtrack annotations not found at {DATASET}")
    return DATASET


def test_import_makes_a_loadable_site_whose_calibration_reprojects_ground_truth(dataset: Path, tmp_path: Path) -> None:
    res = import_wildtrack(dataset, tmp_path / "wt", max_frames=20)
    site = load_site(res.site)
    assert site.dataset is not None and site.dataset.fps == 2.0 and site.dataset.frames == 20
    assert [p.name for p in site.process] == [*res.cameras, "manager"]
    assert res.cameras == ["cvlab1", "cvlab2", "cvlab3", "cvlab4", "idiap1", "idiap2", "idiap3"]
    # Its boxes are annotated floor positions drawn into every view: one shared detector, the annotator.
    node = load_node_config(site.resolve("nodes/cvlab1.toml"))
    assert isinstance(node.source, DetectionsSource) and node.source.shared_detector == "wildtrack-annotation"
    gt = read_gt_csv(site.resolve(site.dataset.ground_truth))
    assert gt.frame_numbers == list(range(1, 21))
    # Camera 0 (CVLab1): the first annotated person's floor point projects to its box bottom-centre.
    first = json.loads((dataset / "annotations_positions" / "00000000.json").read_text())
    cam = PinholeCamera.from_calibration(json.loads((tmp_path / "wt" / "calib" / "cvlab1.json").read_text()), "c")
    errors = []
    for person in first:
        box = next((v for v in person["views"] if v["viewNum"] == 0 and v["xmin"] != -1), None)
        if box is None:
            continue
        p = next(q for q in gt.frames[1] if q.person_id == str(person["personID"]))
        uv, front = cam.project(np.array([[p.x_m, p.y_m, 0.0]]))
        assert front[0]
        errors.append(math.dist(uv[0], ((box["xmin"] + box["xmax"]) / 2, box["ymax"])))
    assert len(errors) > 5
    assert float(np.median(errors)) < 15.0  # ABOUT.md: median 6.4 px over the whole dataset
    # Camera centres 1.7-3.4 m above the floor: t really is in metres.
    assert 1.5 < float(cam.center_world[2]) < 3.6


def test_detections_carry_no_identity_and_noise_and_drops_apply(dataset: Path, tmp_path: Path) -> None:
    clean = import_wildtrack(dataset, tmp_path / "a", max_frames=10)
    noisy = import_wildtrack(dataset, tmp_path / "b", max_frames=10, noise_px=3.0, drop_rate=0.3, seed=4)
    assert clean.dropped == 0 and 0.2 * noisy.boxes < noisy.dropped < 0.4 * noisy.boxes
    a = (tmp_path / "a" / "detections" / "cvlab1.txt").read_text().split()
    b = (tmp_path / "b" / "detections" / "cvlab1.txt").read_text().split()
    assert all(line.split(",")[1] == "-1" for line in a + b)
    assert len(b) < len(a)


def test_cli_refuses_output_inside_the_dataset(dataset: Path) -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "panostereo", "import", "wildtrack", str(dataset), "--out", str(dataset / "x")],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert proc.returncode == 1
    assert "must not be inside the dataset" in proc.stderr
    assert not (dataset / "x").exists()
