"""Still regions: a ghost (someone who stood while the model learnt, then left) is absorbed into the model; a
person who pauses later is kept as an object; a region that keeps moving is never learnt."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from sensor_node.background.still import BORN_FRAMES, CLOSE_REACH_PX, StillRegions, _closed_regions
from sensor_node.config import PipelineSettings

H, W = 120, 160
WALL, PERSON = 120.0, 40.0
BOX = np.zeros((H, W), np.uint8)
cv2.ellipse(BOX, (72, 65), (12, 25), 0.0, 0.0, 360.0, 255, -1)
BOX = BOX > 0
"""Where someone stands: an upright ellipse 25 x 50 px (a silhouette, not its own bounding box)."""


def _with_person(level: float) -> np.ndarray:
    img = np.full((H, W), WALL, np.float32)
    img[BOX] = level
    return img


def _run(regions: StillRegions, frame: np.ndarray, bg: np.ndarray, frames: range, *, moving: bool = False) -> None:
    grey = frame.astype(np.uint8)
    for k in frames:
        bg_u8 = bg.astype(np.uint8)
        fg = np.where(np.abs(grey.astype(np.float32) - bg) > 25.0, 255, 0).astype(np.uint8)
        moved = fg.copy() if moving else np.zeros_like(fg)
        regions.update(grey, fg, lambda moved=moved: moved, bg=bg, bg_u8=bg_u8, frame=k)


def test_a_ghost_left_by_someone_who_stood_while_the_model_learnt_is_absorbed() -> None:
    regions = StillRegions(PipelineSettings())
    bg = _with_person(PERSON)  # the model learnt them standing there
    _run(regions, _with_person(WALL), bg, range(1, 25))  # they have gone: the frame shows the bare wall
    assert regions.ghosts >= 1
    assert np.abs(bg[BOX] - WALL).max() < 1.0  # the model now holds the wall where the ghost was


def test_someone_who_pauses_after_the_model_learnt_is_kept_not_learnt() -> None:
    settings = PipelineSettings()
    regions = StillRegions(settings)
    bg = _with_person(WALL)
    _run(regions, _with_person(WALL), bg, range(1, BORN_FRAMES + 1))  # an empty room first
    _run(regions, _with_person(PERSON), bg, range(BORN_FRAMES + 1, BORN_FRAMES + settings.still_absorb_frames))
    assert regions.ghosts == 0 and regions.kept >= 1
    assert (bg[BOX] == WALL).all()


def test_a_region_that_keeps_moving_is_never_absorbed() -> None:
    regions = StillRegions(PipelineSettings())
    bg = _with_person(PERSON)
    _run(regions, _with_person(WALL), bg, range(1, 80), moving=True)
    assert regions.ghosts == 0 and (bg[BOX] == PERSON).all()


def test_reset_forgets_the_regions_counted_so_far() -> None:
    regions = StillRegions(PipelineSettings())
    bg = _with_person(PERSON)
    young = range(1, BORN_FRAMES + 1)
    _run(regions, _with_person(PERSON), bg, young)  # they stand (in the model) while it is young
    _run(regions, _with_person(WALL), bg, range(BORN_FRAMES + 1, BORN_FRAMES + 9))  # then leave: two samples
    assert regions.ghosts == 0  # not old enough for the ghost test, too late to be a start-up hole
    regions.reset()  # the model is learnt afresh: what is changed now is changed since it was learnt
    _run(regions, _with_person(WALL), bg, range(BORN_FRAMES + 9, BORN_FRAMES + 13))
    assert regions.ghosts == 1 and np.abs(bg[BOX] - WALL).max() < 1.0


def test_a_start_up_hole_goes_at_its_first_still_sample() -> None:
    # Changed ever since the model was learnt, the frame continuing the wall beside it: the surface beside
    # it says it is a hole at once, no outline needs to have stayed for ghost_frames.
    settings = PipelineSettings()
    regions = StillRegions(settings)
    bg = _with_person(PERSON)
    _run(regions, _with_person(WALL), bg, range(1, 5))  # one sample (STATIC_EVERY frames)
    assert settings.ghost_frames > 4
    assert regions.ghosts == 1 and np.abs(bg[BOX] - WALL).max() < 1.0


def test_the_hole_beside_someone_walking_out_of_it_goes_and_they_stay() -> None:
    # They stood in the model while it was learnt and have moved 10 px to the right: their hole (left)
    # and their still inside (a plain shirt does not change from frame to frame) make one region.
    regions = StillRegions(PipelineSettings())
    bg = _with_person(PERSON)
    moved = np.roll(BOX, 10, axis=1)
    frame = np.full((H, W), WALL, np.float32)
    frame[moved] = PERSON
    _run(regions, frame, bg, range(1, 9))
    hole, beside = BOX & ~moved, moved & ~BOX
    assert np.abs(bg[hole] - WALL).mean() < 5.0  # the hole's columns hold the wall again
    assert (bg[beside] == WALL).all()  # they were not painted into the model


@pytest.mark.parametrize("seed", range(6))
def test_regions_far_apart_are_labelled_as_in_one_box(seed: int) -> None:
    """Still pixels in column runs far apart are closed and labelled run by run: the same regions, in the
    same order, with the same boxes, areas and pixels as closing and labelling the box around them all."""
    rng = np.random.default_rng(seed)
    old = np.zeros((140, 900), np.uint8)
    for _ in range(12):
        x, y = int(rng.integers(0, 880)), int(rng.integers(0, 120))
        w, h = int(rng.integers(1, 20)), int(rng.integers(1, 20))
        old[y : y + h, x : x + w] = np.where(rng.random((h, w)) < 0.6, 255, 0)
    bx, by, bw, bh = cv2.boundingRect(old)
    x0, y0 = max(bx - CLOSE_REACH_PX, 0), max(by - CLOSE_REACH_PX, 0)
    box = old[y0 : by + bh + CLOSE_REACH_PX, x0 : bx + bw + CLOSE_REACH_PX]
    n, labels, stats, _ = cv2.connectedComponentsWithStats(cv2.morphologyEx(box, cv2.MORPH_CLOSE, np.ones((5, 5))))
    got_n, got_labels, got_stats, label_x, got_y0 = _closed_regions(old)
    assert (got_n, got_y0) == (n, y0)
    for k in range(1, n):
        x, y, w, h, area = stats[k]
        assert got_stats[k].tolist() == [x + x0, y + y0, w, h, area]
        got = got_labels[y : y + h, label_x[k] : label_x[k] + w] == k
        assert np.array_equal(got, labels[y : y + h, x : x + w] == k)
