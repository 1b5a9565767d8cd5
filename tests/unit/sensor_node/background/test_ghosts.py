"""Ghost helpers of the background model: the model kept from under absorbed ghosts, its expiry, and the hole
columns of a region that holds both a start-up hole and the one walking out of it."""

from __future__ import annotations

import numpy as np

from sensor_node.background.ghosts import RESTORE_FRAMES, UnderGhosts, hole_columns
from tests.unit.sensor_node.sn_synth import H, W


def _absorbed_window() -> tuple[UnderGhosts, np.ndarray, np.ndarray, np.ndarray]:
    """A bright window (grey 230, columns 500..519) wrongly absorbed at frame 10: the model now holds the
    wall (grey 90) there; returns (kept, model, a frame showing the window again, its still pixels)."""
    model = np.full((H, W), 90.0, np.float32)
    model[40:100, 500:520] = 230.0
    kept = UnderGhosts((H, W))
    take = np.zeros((70, 30), bool)
    take[5:65, 5:25] = True  # the box (495, 35) .. (525, 105) around the window
    sub = model[35:105, 495:525]
    kept.keep((495, 35), take, sub, frame=10)
    sub[take] = 90.0  # the absorption
    frame = np.full((H, W), 90, np.uint8)
    frame[40:100, 500:520] = 230
    still = np.zeros((H, W), np.uint8)
    still[40:100, 500:520] = 255
    return kept, model, frame, still


def test_the_model_under_an_absorbed_ghost_is_put_back_where_the_frame_shows_it() -> None:
    kept, model, frame, still = _absorbed_window()
    assert not kept.expired(10 + RESTORE_FRAMES)
    back, regions = kept.restore(frame, still, model, frame=10 + RESTORE_FRAMES, match_level=16, least_px=40)
    assert regions == 1 and back is not None
    assert (back[40:100, 500:520] > 0).all() and not back[:, :490].any()
    assert float(model[40:100, 500:520].min()) == 230.0 and float(model[:, :490].max()) == 90.0


def test_nothing_is_put_back_once_everything_kept_has_expired() -> None:
    kept, model, frame, still = _absorbed_window()
    late = 11 + RESTORE_FRAMES
    assert kept.expired(late)
    back, regions = kept.restore(frame, still, model, frame=late, match_level=16, least_px=40)
    assert back is None and regions == 0
    assert float(model[40:100, 500:520].max()) == 90.0  # an old copy does not come back


def test_a_later_absorption_keeps_the_copy_alive() -> None:
    kept, model, frame, still = _absorbed_window()
    other = np.ones((10, 10), bool)
    kept.keep((100, 20), other, model[20:30, 100:110], frame=50)  # another ghost elsewhere, later
    assert not kept.expired(11 + RESTORE_FRAMES) and kept.expired(51 + RESTORE_FRAMES)
    # The window's own copy is as old as before: not put back after RESTORE_FRAMES.
    back, regions = kept.restore(frame, still, model, frame=11 + RESTORE_FRAMES, match_level=16, least_px=40)
    assert back is None and regions == 0


def test_a_sliver_kept_alone_is_put_back_too() -> None:
    """What is kept may be a sliver a few pixels wide (a fragment of a ghost's edge): put back like a region."""
    model = np.full((H, W), 90.0, np.float32)
    kept = UnderGhosts((H, W))
    sub = model[40:100, 300:303]
    sub[:] = 230.0
    kept.keep((300, 40), np.ones((60, 3), bool), sub, frame=10)
    sub[:] = 90.0  # the absorption
    frame = np.full((H, W), 90, np.uint8)
    frame[40:100, 300:303] = 230
    still = np.zeros((H, W), np.uint8)
    still[40:100, 300:303] = 255
    back, regions = kept.restore(frame, still, model, frame=20, match_level=16, least_px=40)
    assert regions == 1 and back is not None and (back[40:100, 300:303] > 0).all()
    assert float(model[40:100, 300:303].min()) == 230.0


def test_a_single_pixel_kept_is_put_back_as_any_region() -> None:
    model = np.full((H, W), 90.0, np.float32)
    kept = UnderGhosts((H, W))
    kept.keep((300, 40), np.ones((1, 1), bool), model[40:41, 300:301], frame=10)
    model[40, 300] = 200.0  # the absorption
    frame = np.full((H, W), 90, np.uint8)
    still = np.zeros((H, W), np.uint8)
    still[40, 300] = 255
    back, regions = kept.restore(frame, still, model, frame=20, match_level=16, least_px=1)
    assert regions == 1 and back is not None and back[40, 300] == 255 and float(model[40, 300]) == 90.0


def test_hole_columns_part_a_hole_from_the_one_walking_out_of_it() -> None:
    # The model holds someone (grey 40) at columns 100..119 in front of a wall of grey 120; in the frame
    # they have moved to 110..129. One changed region, 100..129: columns 100..109 are their hole (the
    # frame continues the wall), 110..119 them in both (unchanged), 120..129 them over the wall.
    model = np.full((H, W), 120, np.uint8)
    model[30:130, 100:120] = 40
    frame = np.full((H, W), 120, np.uint8)
    frame[30:130, 110:130] = 40
    fg = np.where(np.abs(frame.astype(np.int16) - model) > 25, 255, 0).astype(np.uint8)
    mask = np.ones((100, 30), bool)  # the region's box, (100, 30) .. (130, 130)
    holes = hole_columns(frame, model, fg, mask, (100, 30))
    assert holes[:10].all()
    assert not holes[10:].any()
