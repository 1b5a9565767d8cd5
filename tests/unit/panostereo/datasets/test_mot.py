"""``panostereo import mot`` (panostereo/datasets/mot.py): a dataset made in the test, and the shared PETS 2009
detections (passed by path, never copied)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from common.area import AreaSpec, rectangle
from common.errors import ConfigError
from common.site import load_site
from panostereo.datasets.mot import import_mot
from sensor_node.config import DetectionsSource, load_node_config
from tests.support import REPO, skip_or_fail
from tests.unit.panostereo.mot_synth import CAMERAS
from user_agent.groundtruth import read_gt_csv

PETS = REPO.parent / "shared" / "datasets" / "pets2009_s2l1"


def test_import_writes_a_site_of_the_dataset_facts_only(made: Path, tmp_path: Path) -> None:
    res = import_mot(made, tmp_path / "site", fps=5.0, area=rectangle(0, 0, 10, 10), min_confidence=0.5)
    site = load_site(res.site)
    assert res.cameras == sorted(CAMERAS) and res.frames == 30 and res.people == 3
    assert site.dataset is not None and site.dataset.fps == 5.0 and site.dataset.frames == 30
    assert [p.name for p in site.process] == [*sorted(CAMERAS), "manager"]
    node = load_node_config(site.resolve("nodes/north.toml"))
    assert isinstance(node.source, DetectionsSource)
    assert node.source.fps == 5.0 and node.source.min_confidence == 0.5
    assert node.source.shared_detector == ""  # each camera's boxes are its own detector's unless said
    shared = import_mot(made, tmp_path / "shared", fps=5.0, shared_detector="mvdetr")
    one = load_node_config(load_site(shared.site).resolve("nodes/east.toml"))
    assert isinstance(one.source, DetectionsSource) and one.source.shared_detector == "mvdetr"
    assert node.resolve(node.source.file).read_text() == (made / "detections" / "north.txt").read_text()
    manager = (tmp_path / "site" / "nodes" / "manager.toml").read_text()
    # Facts only: the area, in the site; no [match] or [tracker] tuning.
    assert site.area is not None and site.area.polygon == [[0, 0], [10, 0], [10, 10], [0, 10]]
    assert site.area.exits is None  # people come and go anywhere on its boundary
    assert "[match]" not in manager and "[tracker]" not in manager


def test_import_perturbs_boxes_when_asked_and_refuses_bad_input(made: Path, tmp_path: Path) -> None:
    res = import_mot(made, tmp_path / "noisy", fps=5.0, noise_px=2.0, drop_rate=0.3, seed=1)
    assert 0.2 * res.boxes < res.dropped < 0.4 * res.boxes
    a = (made / "detections" / "east.txt").read_text().splitlines()
    b = (tmp_path / "noisy" / "detections" / "east.txt").read_text().splitlines()
    assert len(b) < len(a) and b[0] != a[0]
    for kwargs, message in [
        ({"fps": 0.0}, "--fps"),
        ({"fps": 5.0, "area": AreaSpec(polygon=[[0, 0], [1, 1], [2, 2]])}, "--area.polygon encloses no area"),
        ({"fps": 5.0, "drop_rate": 1.0}, "--drop-rate"),
        ({"fps": 5.0, "min_confidence": 2.0}, "--min-confidence"),
        ({"fps": 5.0, "shared_detector": "MV DeTr"}, "--shared-detector"),
    ]:
        with pytest.raises(ConfigError, match=message):
            import_mot(made, tmp_path / "bad", **kwargs)  # type: ignore[arg-type]
    (tmp_path / "empty").mkdir()
    with pytest.raises(ConfigError, match=r"calib/<cam>\.json and detections/<cam>\.txt"):
        import_mot(tmp_path / "empty", tmp_path / "out", fps=5.0)
    with pytest.raises(ConfigError, match="inside the dataset"):
        import_mot(made, made / "site", fps=5.0)


def test_pets_worked_example(tmp_path: Path) -> None:
    """The README's worked example on the shared PETS 2009 S2.L1 detections (a real detector's boxes)."""
    if not (PETS / "detections").is_dir():
        skip_or_fail(f"PETS 2009 detections not found at {PETS}")
    res = import_mot(PETS, tmp_path / "pets", fps=7.0, min_confidence=0.5)
    assert len(res.cameras) == 7 and res.frames == 795
    site = load_site(res.site)
    assert site.site.name == "pets2009-s2l1"
    gt = read_gt_csv(site.resolve("gt.csv"))
    assert len(gt.person_ids) == 19 and np.isclose(gt.frames[1][0].x_m, -4.2124)
