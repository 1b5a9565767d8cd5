"""The top view: each track drawn in its id's colour where it walked (x right, y up), ground truth beside, a PNG."""

from __future__ import annotations

from pathlib import Path

import cv2
import msgspec
import numpy as np
import pytest

from common.errors import ConfigError
from common.schema import TrackSet
from tests.unit.user_agent.recorded_run import EPOCH, sensor_info, track
from user_agent.colors import id_color_bgr
from user_agent.groundtruth import GroundTruth, GtPoint
from user_agent.plot import PlotInput, render_top_view, save_top_view

ROOM = (0.0, 0.0, 8.0, 6.0)


def _input(with_gt: bool = False, state: str = "confirmed") -> PlotInput:
    sets = []
    for i in range(30):
        x = 1.0 + 6.0 * i / 29
        low, high = track("mgr1-1", x, 1.0, EPOCH + i), track("mgr1-2", x, 5.0, EPOCH + i)
        sets.append(
            TrackSet(
                manager_id="mgr1", seq=i, stamp_ns=EPOCH + i, tracks=[low, msgspec.structs.replace(high, state=state)]
            )
        )
    gt = GroundTruth({k: [GtPoint(k, "7", 4.0, 1.0 + 4.0 * k / 29)] for k in range(30)}) if with_gt else None
    infos = [sensor_info("pano1", 0.5, 0.5), sensor_info("pano2", 7.5, 0.5)]
    return PlotInput(tracksets=sets, sensor_infos=infos, pairs=[], ground_truth=gt, room_m=ROOM)


def _where(img: np.ndarray, bgr: tuple[int, int, int]) -> tuple[np.ndarray, np.ndarray]:
    rows, cols = np.nonzero((np.abs(img.astype(int) - bgr) <= 2).all(axis=2))
    assert rows.size > 50, f"colour {bgr} not drawn"
    return rows, cols


def test_each_track_is_drawn_in_its_colour_where_it_walked() -> None:
    img = render_top_view(_input())
    low_rows, low_cols = _where(img, id_color_bgr("mgr1-1"))
    high_rows, high_cols = _where(img, id_color_bgr("mgr1-2"))
    width = img.shape[1]
    # Both walked x = 1 -> 7 of an 8 m room: most of the width, left to right.
    for cols in (low_cols, high_cols):
        assert np.ptp(cols) > 0.6 * width
    assert np.median(low_rows) > np.median(high_rows) + 0.4 * img.shape[0]  # y = 1 below y = 5 (y up)


def test_only_the_chosen_states_are_drawn() -> None:
    img = render_top_view(_input(state="tentative"))
    _where(img, id_color_bgr("mgr1-1"))
    assert (np.abs(img.astype(int) - id_color_bgr("mgr1-2")) <= 2).all(axis=2).sum() < 10  # a tentative track


def test_ground_truth_goes_in_a_second_panel_of_the_same_size() -> None:
    alone, both = render_top_view(_input()), render_top_view(_input(with_gt=True))
    assert both.shape[0] == alone.shape[0] and both.shape[1] == 2 * alone.shape[1] + 12
    rows, cols = _where(both, id_color_bgr("gt-7"))
    assert cols.min() > alone.shape[1]  # in the right-hand panel
    assert np.ptp(rows) > np.ptp(cols) * 3  # walked along y: a vertical line


def test_save_writes_a_png_and_refuses_what_cannot_be_written(tmp_path: Path) -> None:
    out = save_top_view(_input(), tmp_path / "sub" / "top.png")
    assert out.is_file() and cv2.imread(str(out)).shape == render_top_view(_input()).shape
    with pytest.raises(ConfigError, match=r"top\.unknown"):
        save_top_view(_input(), tmp_path / "top.unknown")
    empty = PlotInput(tracksets=[], sensor_infos=[], pairs=[], room_m=(1.0, 1.0, 1.0, 4.0))
    with pytest.raises(ConfigError, match="extent"):
        render_top_view(empty)
