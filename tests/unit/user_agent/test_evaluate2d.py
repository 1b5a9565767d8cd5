"""Detection accuracy in the image on hand-made boxes: IoU, one-to-one matching, merged blobs, the box file reader."""

from __future__ import annotations

from pathlib import Path

import pytest

from common.errors import ConfigError
from user_agent.evaluate2d import Box, Detection2D, iou_matrix, read_boxes, score_detections


def test_iou_of_identical_half_overlapping_and_disjoint_boxes() -> None:
    a = Box(0.0, 0.0, 10.0, 10.0)
    iou = iou_matrix([a], [a, Box(5.0, 0.0, 10.0, 10.0), Box(20.0, 20.0, 5.0, 5.0)])
    assert iou.shape == (1, 3)
    assert iou[0].tolist() == pytest.approx([1.0, 50.0 / 150.0, 0.0])


def test_one_match_one_miss_one_false_positive_and_a_merged_blob() -> None:
    truth = {1: [Box(0, 0, 10, 20), Box(100, 0, 10, 20)], 2: [Box(0, 0, 10, 20), Box(12, 0, 10, 20)]}
    found = {
        1: [Detection2D(Box(1, 0, 10, 20)), Detection2D(Box(50, 50, 10, 20))],  # a match and a false positive
        2: [Detection2D(Box(0, 0, 22, 20))],  # one blob over both people
    }
    s05, s03 = score_detections(truth, found, [1, 2])
    assert (s05.iou, s03.iou) == (0.5, 0.3)
    assert s05.frames == 2 and s05.objects == 4 and s05.blobs == 3
    # the merged blob overlaps the first person of frame 2 by IoU 200/440: a match at 0.3, not at 0.5
    assert (s05.matches, s05.misses, s05.false_positives) == (1, 3, 2)
    assert (s03.matches, s03.misses, s03.false_positives) == (2, 2, 1)
    assert s05.merged == 2  # both people of frame 2 inside the one blob
    assert s05.no_blob == 1  # the person at x = 100 in frame 1
    summary = s03.summary()
    assert summary["recall"] == 0.5 and summary["precision"] == round(2 / 3, 4) and summary["moda"] == 0.25


def test_bearing_error_and_ignored_blobs_above_a_row() -> None:
    truth = {1: [Box(0, 10, 10, 20)]}
    found = {1: [Detection2D(Box(0, 10, 10, 20), bearing_rad=0.01), Detection2D(Box(50, 0, 5, 5))]}
    (sc,) = score_detections(truth, found, [1], thresholds=[0.5], bearing_of=lambda u, v: 0.0, ignore_above_row=8.0)
    assert sc.false_positives == 0 and sc.blobs == 1  # the small blob ends above row 8: not counted
    assert sc.bearing_err_deg == pytest.approx([0.5729578], rel=1e-6)


def test_read_boxes_groups_by_frame_and_names_a_bad_line(tmp_path: Path) -> None:
    good = tmp_path / "gt.txt"
    good.write_text("# frame,id,left,top,width,height\n1,1,10,20,30,40\n1,2,0,0,5,5\n3,1,1,2,3,4,1,-1\n")
    boxes = read_boxes(good)
    assert sorted(boxes) == [1, 3] and boxes[1][0] == Box(10.0, 20.0, 30.0, 40.0) and boxes[1][0].bottom_px == 60.0
    bad = tmp_path / "bad.txt"
    bad.write_text("1,1,10,20,30,40\n2,1,ten,20,30,40\n")
    with pytest.raises(ConfigError, match=r"bad.txt:2: expected"):
        read_boxes(bad)
    empty = tmp_path / "none.txt"
    empty.write_text("1,1,10,20,0,40\n")
    with pytest.raises(ConfigError, match="positive finite box"):
        read_boxes(empty)
