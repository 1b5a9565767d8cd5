"""Ground truth CSV: written and read back, its scored area, and bad rows refused naming the line."""

from __future__ import annotations

from pathlib import Path

import pytest

from common.errors import ConfigError
from user_agent.groundtruth import GtPoint, read_gt_csv, write_gt_rows


def test_rows_round_trip_by_frame_and_person(tmp_path: Path) -> None:
    points = [GtPoint(2, "b", 1.0, 2.0, 1.7), GtPoint(1, "a", 0.0, 0.0, 1.8), GtPoint(2, "a", 3.0, 0.5, 1.8)]
    assert write_gt_rows(tmp_path / "gt.csv", points) == 3
    gt = read_gt_csv(tmp_path / "gt.csv")
    assert gt.frame_numbers == [1, 2] and gt.person_ids == ["a", "b"]
    assert [(p.frame, p.x_m) for p in gt.track_of("a")] == [(1, 0.0), (2, 3.0)]
    assert gt.frames[2][1].z_m == pytest.approx(1.7) or gt.frames[2][0].z_m == pytest.approx(1.7)
    area = gt.area()
    assert area is not None and sorted(map(tuple, area.tolist())) == [(0.0, 0.0), (1.0, 2.0), (3.0, 0.5)]


def test_area_needs_three_points_off_a_line(tmp_path: Path) -> None:
    write_gt_rows(tmp_path / "gt.csv", [GtPoint(k, "a", float(k), 0.0, 1.7) for k in range(1, 5)], with_z=False)
    assert read_gt_csv(tmp_path / "gt.csv").area() is None


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("frame,id,x\n1,a,0\n", "expected a header with frame,id,x_m,y_m"),
        ("frame,id,x_m,y_m\n1,a,0,0\none,a,0,0\n", r"gt.csv:3: frame must be an integer, got 'one'"),
        ("frame,id,x_m,y_m\n0,a,0,0\n", "frame must be >= 1"),
        ("frame,id,x_m,y_m\n1,,0,0\n", "id must not be empty"),
        ("frame,id,x_m,y_m\n1,a,nan,0\n", "x_m must be a finite number"),
    ],
)
def test_bad_files_are_refused_naming_the_line(tmp_path: Path, text: str, message: str) -> None:
    (tmp_path / "gt.csv").write_text(text)
    with pytest.raises(ConfigError, match=message):
        read_gt_csv(tmp_path / "gt.csv")


def test_a_missing_file_is_a_config_error(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="no such ground-truth file"):
        read_gt_csv(tmp_path / "none.csv")


@pytest.mark.parametrize(("fps", "warns"), [(10.0, False), (100.0, True), (0.5, True), (7e9, True)])
def test_a_frame_rate_that_makes_people_walk_implausibly_is_named(fps: float, warns: bool) -> None:
    from user_agent.groundtruth import GroundTruth, GtPoint, median_speed_mps, speed_warning

    # Two people 0.12 m apart from frame to frame (1.2 m/s at 10 fps), one standing.
    gt = GroundTruth({k: [GtPoint(k, "a", 0.12 * k, 0.0), GtPoint(k, "b", 0.0, 0.12 * k), GtPoint(k, "c", 5.0, 5.0)]
                      for k in range(1, 30)}, "gt.csv")  # fmt: skip
    assert median_speed_mps(gt, 10.0) == pytest.approx(1.2)
    warning = speed_warning(gt, fps)
    assert (warning is not None) == warns
    if warning:
        assert f"at {fps:g} fps" in warning and "is the frame rate right?" in warning
