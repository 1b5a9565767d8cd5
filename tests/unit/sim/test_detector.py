"""The simulated corner-camera detector: a dataset in the mot layout, misses and cut boxes where people hide
each other, one ground-truth id per stay in the room, the same files from the same seed."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from common.errors import ConfigError
from common.pinhole import PinholeCamera
from sim.detector import DetectorModel, write_room_dataset
from user_agent.groundtruth import read_gt_csv


def test_a_room_dataset_is_the_mot_layout_and_the_same_from_the_same_seed(tmp_path: Path) -> None:
    a = write_room_dataset(tmp_path / "a", people=6, duration_s=20.0, seed=3)
    b = write_room_dataset(tmp_path / "b", people=6, duration_s=20.0, seed=3)
    cams = sorted(p.stem for p in (a / "calib").glob("*.json"))
    assert cams == ["cam1", "cam2", "cam3", "cam4"]
    for cam in cams:
        assert (a / "detections" / f"{cam}.txt").read_text() == (b / "detections" / f"{cam}.txt").read_text()
        PinholeCamera.from_calibration(__import__("json").loads((a / "calib" / f"{cam}.json").read_text()), cam)
    gt = read_gt_csv(a / "gt.csv")
    assert len(gt.frame_numbers) == 80 and all(
        0 <= p.x_m <= 8 and 0 <= p.y_m <= 6 for f in gt.frames.values() for p in f
    )


def test_people_hidden_by_others_are_missed_or_cut_and_clutter_is_low_scored(tmp_path: Path) -> None:
    perfect = DetectorModel(p_detect=1.0, box_noise=0.0, clutter_per_frame=0.0, double_prob=0.0)
    root = write_room_dataset(tmp_path / "r", people=12, duration_s=30.0, seed=5, detector=perfect)
    gt = read_gt_csv(root / "gt.csv")
    seen = sum(len(f) for f in gt.frames.values())
    boxes = [line.split(",") for line in (root / "detections" / "cam1.txt").read_text().split()]
    assert 0.3 * seen < len(boxes) < seen  # twelve people in a room: someone is always behind someone
    scores = np.array([float(b[6]) for b in boxes])
    assert scores.min() < 0.9 < scores.max()  # partly hidden people are found with lower scores
    noisy = write_room_dataset(tmp_path / "n", people=0, duration_s=30.0, seed=5, detector=DetectorModel())
    clutter = [float(line.split(",")[6]) for line in (noisy / "detections" / "cam1.txt").read_text().split()]
    assert clutter and max(clutter) <= 0.7  # nobody there: only false boxes


def test_leaving_and_coming_back_is_a_new_ground_truth_identity(tmp_path: Path) -> None:
    gt = read_gt_csv(write_room_dataset(tmp_path / "v", people=8, duration_s=90.0, seed=2) / "gt.csv")
    visits = {pid.split(".")[0] for pid in gt.person_ids if not pid.endswith(".1")}
    assert visits  # somebody came back in: a second stay is id "person.2"


@pytest.mark.parametrize("bad", [{"fps": 0.0}, {"people": 100}, {"room_m": (0.0, 6.0)}])
def test_bad_arguments_are_named(tmp_path: Path, bad: dict[str, object]) -> None:
    with pytest.raises(ConfigError, match="room dataset"):
        write_room_dataset(tmp_path / "x", **bad)  # type: ignore[arg-type]
