"""Still regions: a ghost (someone who stood while the model learnt, then left) is absorbed into the model; a
person who pauses later is kept as an object; a region that keeps moving is never learnt."""

from __future__ import annotations

import cv2
import numpy as np

from sensor_node.background.still import BORN_FRAMES, StillRegions
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
    _run(regions, _with_person(WALL), bg, range(1, 9))  # two samples: not yet old enough
    regions.reset()
    _run(regions, _with_person(WALL), bg, range(9, 13))  # one more sample after the reset: counted afresh
    assert regions.ghosts == 0 and (bg[BOX] == PERSON).all()
