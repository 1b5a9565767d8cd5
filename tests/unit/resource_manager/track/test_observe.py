"""Visibility: who a camera can see past the people nearer to it."""

from __future__ import annotations

import numpy as np
import pytest

from resource_manager.track.model import TrackModel
from resource_manager.track.observe import TrackTable, visibility
from resource_manager.views.blobs import ViewBlobs


def _panorama(origin: tuple[float, float], z_m: float) -> ViewBlobs:
    empty = np.zeros(0)
    return ViewBlobs("c", np.array(origin), z_m, 0.0035, empty, empty, empty, None, np.zeros(0, np.int64))


def _table(*xy: tuple[float, float], height: float = 1.7) -> TrackTable:
    n = len(xy)
    return TrackTable(
        np.array(xy, dtype=float), np.repeat(np.eye(2)[None] * 0.01, n, 0), np.full(n, height), np.full(n, 0.01)
    )


def test_someone_behind_a_nearer_person_is_hidden_from_a_low_camera_not_from_a_high_one() -> None:
    """Angular silhouettes: at head height the far person's head is covered; from 6 m up it shows."""
    model = TrackModel()
    table = _table((3.0, 0.0), (6.0, 0.0), (3.0, 3.0))
    low = visibility(_panorama((0.0, 0.0), 1.1), table, model, 100.0)
    high = visibility(_panorama((0.0, 0.0), 6.0), table, model, 100.0)
    assert low[0] == pytest.approx(model.p_detect) and low[2] == pytest.approx(model.p_detect)
    assert low[1] < 0.5  # wholly behind the nearer one
    assert high[1] > 0.7  # mostly visible above the nearer one's head
    far = _table((200.0, 0.0))
    assert visibility(_panorama((0.0, 0.0), 1.1), far, model, 100.0)[0] == 0.0  # out of range: no evidence either way
