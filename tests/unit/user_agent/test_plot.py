"""The picture: tracks coloured like the person each followed, ground truth beside, a timeline below in which an
id switch shows; colours from a colour-blind-safe palette; the view sized to where people are, not the cameras."""

from __future__ import annotations

from pathlib import Path

import cv2
import matplotlib.colors as mcolors
import numpy as np
import pytest

from common.errors import ConfigError
from common.schema import TrackSet
from tests.unit.user_agent.recorded_run import EPOCH, sensor_info, track
from user_agent.groundtruth import GroundTruth, GtPoint
from user_agent.plot import (
    PALETTE,
    PlotInput,
    _extent,
    bar_names,
    colours_of,
    render_top_view,
    save_top_view,
    timeline_head,
)
from user_agent.timeline import timeline_with_truth

FPS = 10.0
ROOM = (0.0, 0.0, 8.0, 6.0)


def _input(*, with_gt: bool = True, switch: bool = False, far_camera: bool = False, room: bool = True) -> PlotInput:
    """Person "1" walks y = 1, person "2" y = 5, x 1 -> 7 over 30 frames; with ``switch`` person 1's track changes
    id halfway (mgr1-1 -> mgr1-3)."""
    sets, truth = [], {}
    for k in range(1, 31):
        x, stamp = 1.0 + 6.0 * (k - 1) / 29, EPOCH + round((k - 1) / FPS * 1e9)
        first = "mgr1-3" if switch and k > 15 else "mgr1-1"
        sets.append(TrackSet(manager_id="mgr1", seq=k, stamp_ns=stamp,
                             tracks=[track(first, x, 1.0, stamp), track("mgr1-2", x, 5.0, stamp)]))  # fmt: skip
        truth[k] = [GtPoint(k, "1", x, 1.0), GtPoint(k, "2", x, 5.0)]
    infos = [sensor_info("pano1", 0.5, 0.5), sensor_info("pano2", 7.5, 0.5)]
    if far_camera:
        infos.append(sensor_info("far", 60.0, -40.0))
    return PlotInput(tracksets=sets, sensor_infos=infos, pairs=[], ground_truth=GroundTruth(truth) if with_gt else None,
                     room_m=ROOM if room else None, epoch_ns=EPOCH, fps=FPS)  # fmt: skip


def _rgb(colour: str) -> tuple[int, int, int]:
    r, g, b = mcolors.to_rgb(colour)
    return (round(r * 255), round(g * 255), round(b * 255))


def _pixels(img: np.ndarray, colour: str, rows: slice = slice(None), tol: int = 3) -> int:
    return int((np.abs(img[rows].astype(int) - _rgb(colour)) <= tol).all(axis=2).sum())


def test_palette_is_matplotlib_s_colour_blind_safe_one_and_people_get_distinct_colours() -> None:
    import matplotlib.pyplot as plt

    assert list(PALETTE) == plt.style.library["petroff10"]["axes.prop_cycle"].by_key()["color"]
    inp = _input(switch=True)
    assert inp.ground_truth is not None
    tl = timeline_with_truth(inp.tracksets, inp.ground_truth, epoch_ns=EPOCH, fps=FPS)
    rows, tracks = colours_of(tl)
    assert rows == {"1": PALETTE[0], "2": PALETTE[1]}
    # Each track is coloured like the person it followed: both of person 1's ids in person 1's colour.
    assert tracks == {"mgr1-1": PALETTE[0], "mgr1-3": PALETTE[0], "mgr1-2": PALETTE[1]}


def test_an_id_switch_is_a_black_bar_in_the_person_s_row_of_the_timeline() -> None:
    clean, switched = render_top_view(_input()), render_top_view(_input(switch=True))
    assert clean.shape == switched.shape
    lower = slice(clean.shape[0] // 2, None)  # the timeline is below the top views
    black = (0, 0, 0)
    assert _pixels(clean, "#000000", lower) < _pixels(switched, "#000000", lower)
    assert (np.abs(switched[lower].astype(int) - black) <= 3).all(axis=2).any(axis=0).sum() >= 2
    # Both people's rows are there, each in its person's colour.
    for colour in PALETTE[:2]:
        assert _pixels(clean, colour, lower) > 2000


def test_the_timeline_counts_switches_as_the_score_does_from_the_end_of_the_warm_up() -> None:
    """Person 1's track changes id at 1.5 s: scored from 1.0 s it is one switch; scored from 2.0 s none, and the
    title says one more in the warm-up (the run's title counts from there too)."""
    inp = _input(switch=True)
    assert inp.ground_truth is not None
    tl = timeline_with_truth(inp.tracksets, inp.ground_truth, epoch_ns=EPOCH, fps=FPS)
    assert timeline_head(tl, 1.0).endswith("one row per person, 1 id switch")
    assert timeline_head(tl, 2.0).endswith("0 id switches (1 more in the warm-up)")


def test_tracks_and_ground_truth_panels_draw_each_person_in_one_colour() -> None:
    img = render_top_view(_input())
    upper = slice(0, img.shape[0] // 2)
    half = img.shape[1] // 2
    for colour in PALETTE[:2]:
        left = _pixels(img[:, :half], colour, upper, tol=40)  # thin anti-aliased lines
        right = _pixels(img[:, half:], colour, upper, tol=40)
        assert left > 100 and right > 100, (colour, left, right)


def test_the_view_is_the_people_s_floor_not_the_cameras() -> None:
    ext = _extent(_input(far_camera=True, room=False))
    assert ext[0] > -1.0 and ext[2] < 9.0 and ext[1] > -1.0 and ext[3] < 7.0  # the camera at (60, -40) is not in it
    area = [(0.0, 0.0), (10.0, 0.0), (10.0, 8.0), (0.0, 8.0)]
    inp = _input(room=False)
    declared = PlotInput(tracksets=inp.tracksets, sensor_infos=inp.sensor_infos, pairs=[], area=area)
    assert _extent(declared) == (-0.5, -0.5, 10.5, 8.5)


def test_without_ground_truth_one_row_per_track() -> None:
    img = render_top_view(_input(with_gt=False, switch=True))
    lower = slice(img.shape[0] // 2, None)
    for colour in PALETTE[:3]:  # three tracks, three rows, three colours
        assert _pixels(img, colour, lower) > 500


def test_save_writes_a_png_and_refuses_what_cannot_be_written(tmp_path: Path) -> None:
    out = save_top_view(_input(), tmp_path / "sub" / "top.png")
    img = cv2.imread(str(out))
    assert img is not None and img.shape[:2] == render_top_view(_input()).shape[:2]
    with pytest.raises(ConfigError, match=r"top\.unknown"):
        save_top_view(_input(), tmp_path / "top.unknown")
    empty = PlotInput(tracksets=[], sensor_infos=[], pairs=[], room_m=(1.0, 1.0, 1.0, 4.0))
    with pytest.raises(ConfigError, match="extent"):
        render_top_view(empty)


def test_timeline_bars_name_tracks_so_that_two_managers_ids_differ() -> None:
    assert bar_names(["mgr1-3", "mgr1-12"]) == {"mgr1-3": "3", "mgr1-12": "12"}
    names = bar_names(["mgr-nw-7", "mgr-ne-7", "mgr-nw-12"])
    assert names == {"mgr-nw-7": "nw-7", "mgr-ne-7": "ne-7", "mgr-nw-12": "nw-12"}
    assert bar_names(["west1-2", "east1-2"]) == {"west1-2": "west1-2", "east1-2": "east1-2"}
