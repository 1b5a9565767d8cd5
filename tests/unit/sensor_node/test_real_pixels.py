"""What real cameras showed (PETS 2009 S2L1 View_001, issue 14), on synthetic perspective frames and a cut-out
of the shared clip: cast shadows, a flapping distractor, sparse changed pixels between people, frame size
against the calibration, and the offline evaluation command."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from common.errors import ConfigError, SourceError
from common.pinhole import PinholeCamera
from panostereo.cli import main as panostereo_main
from sensor_node.config import PipelineSettings, load_node_config
from sensor_node.features import PinholeGeometry
from sensor_node.pipeline import ImagePipeline
from tests.support import REPO, skip_or_fail

W, H, FPS = 320, 240, 7.0
PETS = REPO.parent / "shared" / "datasets" / "pets2009_s2l1"


def _camera() -> PinholeCamera:
    """5 m up, looking 45 deg down along +x: the whole image is floor (below the horizon)."""
    s = c = math.sqrt(0.5)
    r = np.array([[0.0, -1.0, 0.0], [-s, 0.0, -c], [c, 0.0, -s]])
    centre = np.array([0.0, 0.0, 5.0])
    k = np.array([[300.0, 0, W / 2], [0, 300.0, H / 2], [0, 0, 1]])
    return PinholeCamera(k, np.zeros(0), r, -r @ centre, W, H)


def _ground(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    base = np.empty((H, W, 3), np.float32)
    base[:] = (120, 128, 132)  # grey asphalt (BGR)
    base += rng.normal(0, 6, (H, W, 1)).astype(np.float32)  # texture
    return base


def _frame(base: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    return np.clip(base + rng.normal(0, 2.0, base.shape), 0, 255).astype(np.uint8)


def _person(img: np.ndarray, u: int, v_top: int, shadow: bool) -> None:
    img[v_top : v_top + 60, u : u + 16] = (40, 40, 160)  # red coat, 16 x 60 px
    img[v_top - 10 : v_top, u + 4 : u + 12] = (60, 90, 140)  # head
    if shadow:  # cast to the right along the ground: the asphalt dimmed to 70 %, hue and texture kept
        img[v_top + 45 : v_top + 60, u + 16 : u + 56] *= 0.7


def _run(frames: list[np.ndarray], settings: PipelineSettings | None = None) -> list:
    pipe = ImagePipeline("cam", PinholeGeometry(_camera()), settings or PipelineSettings())
    return [pipe.process(f, round(k * 1e9 / FPS), k) for k, f in enumerate(frames)]


@pytest.mark.parametrize("shadows", [True, False])
def test_a_cast_shadow_is_not_part_of_the_blob(shadows: bool) -> None:
    rng = np.random.default_rng(1)
    base = _ground(1)
    frames = [_frame(base, rng) for _ in range(14)]
    for k in range(6):
        img = base.copy()
        _person(img, 100 + 2 * k, 100, shadow=True)
        frames.append(_frame(img, rng))
    out = _run(frames, PipelineSettings(shadows=shadows))
    blobs = out[-1].features.blobs
    assert len(blobs) == 1
    width = blobs[0].bbox_w_px
    if shadows:
        assert width <= 20, f"blob {width} px wide: the shadow is in it (person 16 px)"
    else:  # grey levels alone: the shadow is joined to the person (the case the colour test exists for)
        assert width >= 40


def test_a_flapping_tape_is_absorbed_and_a_person_beside_it_found() -> None:
    rng = np.random.default_rng(2)
    base = _ground(2)
    frames = []
    for k in range(40):
        img = base.copy()
        row = 60 + (k * 7) % 5  # the tape jumps between rows from frame to frame
        img[row : row + 3, 20:300] = (230, 230, 240) if k % 2 else (40, 40, 200)  # red and white stripes
        if k >= 28:
            _person(img, 150, 120, shadow=False)
        frames.append(_frame(img, rng))
    out = _run(frames)
    assert out[12].state == "ok"  # start-up within 1.5 s of stamps at 7 fps
    for res in out[20:28]:
        assert not res.features.blobs, "the tape is reported as an object"
    last = out[-1].features.blobs
    assert len(last) == 1 and 140 <= last[0].bbox_u_px <= 160 and last[0].bbox_w_px <= 24


def test_sparse_changes_between_two_people_do_not_chain_them() -> None:
    rng = np.random.default_rng(3)
    base = _ground(3)
    frames = [_frame(base, rng) for _ in range(14)]
    for _ in range(4):
        img = base.copy()
        _person(img, 100, 100, shadow=False)
        _person(img, 150, 104, shadow=False)
        speck = rng.random((60, 34)) < 0.08  # a frame-difference trail / compression speckle
        img[110:170, 116:150][speck] = (200, 200, 200)
        frames.append(_frame(img, rng))
    blobs = _run(frames)[-1].features.blobs
    assert sorted(round(b.bbox_u_px) for b in blobs) == [100, 150]
    assert all(b.bbox_w_px <= 20 for b in blobs)


def test_frames_of_another_size_than_the_calibration_are_refused() -> None:
    pipe = ImagePipeline("cam", PinholeGeometry(_camera()), PipelineSettings())
    with pytest.raises(SourceError, match=r"frame is 640x480 px but the camera calibration is for 320x240"):
        pipe.process(np.zeros((480, 640, 3), np.uint8), 0, 0)


def test_a_pose_beside_a_pinhole_calibration_is_refused(tmp_path: Path) -> None:
    cfg = tmp_path / "cam.toml"
    cfg.write_text(
        '[node]\nid = "cam"\n[source]\nkind = "opencv"\nuri = "clip.avi"\nat_end = "exit"\n'
        '[camera]\nmodel = "pinhole"\ncalibration = "cam.json"\n[pose]\nx_m = 1.0\ny_m = 2.0\nz_m = 3.0\n'
    )
    with pytest.raises(ConfigError, match=r"\[pose\]: a calibrated pinhole camera takes its pose from its calibration"):
        load_node_config(cfg)
    cfg.write_text(cfg.read_text().split("[pose]")[0])
    assert load_node_config(cfg).source.at_end == "exit"  # type: ignore[union-attr]


def test_evaluate_detections_on_a_cut_of_the_pets_clip(capsys: pytest.CaptureFixture[str]) -> None:
    video = PETS / "video" / "view001_0000-0399.avi"
    if not video.is_file():
        skip_or_fail(f"PETS clip not found at {video}")
    args = [
        "evaluate-detections", str(video), "--ground-truth", str(PETS / "video" / "view001_gt_boxes.txt"),
        "--calibration", str(PETS / "calib" / "view001.json"), "--fps", "7", "--max-frames", "60", "--json",
    ]  # fmt: skip
    assert panostereo_main(args) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["frames"] == 60 and out["scored_frames"] == 46
    assert out["startup_s"] is not None and out["startup_s"] <= 2.0
    loose, strict = out["iou_0.3"], out["iou_0.5"]
    assert loose["recall"] >= 0.6 and loose["precision"] >= 0.6
    assert strict["recall"] <= loose["recall"]
    assert strict["bearing_err_deg_median"] is not None and strict["bearing_err_deg_median"] < 1.0
    bad = ["evaluate-detections", str(video), "--ground-truth", str(video), "--calibration", str(video)]
    assert panostereo_main(bad) == 1
