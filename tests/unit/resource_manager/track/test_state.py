"""A track's record: existence from log-odds, what is published, its state, its worst-direction position error."""

from __future__ import annotations

import math

import numpy as np
import pytest

from resource_manager.track.state import TrackRecord


def _record(logodds: float, confirmed: bool, detected: bool, p_xy: list[list[float]] | None = None) -> TrackRecord:
    p = np.eye(4) * 0.01
    if p_xy is not None:
        p[:2, :2] = p_xy
    x = np.array([1.0, 2.0, 0.0, 0.0])
    return TrackRecord(0, x, p, 0, 0, logodds, 1.7, 0.01, confirmed=confirmed, detected=detected)


@pytest.mark.parametrize(
    ("logodds", "confirmed", "detected", "state", "published"),
    [
        (2.0, False, True, "tentative", False),
        (2.0, True, True, "confirmed", True),
        (0.5, True, False, "coasting", True),
        (-0.5, True, False, "coasting", False),  # kept for its id, not reported
    ],
)
def test_state_and_publication(logodds: float, confirmed: bool, detected: bool, state: str, published: bool) -> None:
    rec = _record(logodds, confirmed, detected)
    assert rec.state == state and rec.published is published
    assert rec.existence == pytest.approx(1.0 / (1.0 + math.exp(-logodds)))
    assert list(rec.xy) == [1.0, 2.0]


def test_position_sigma_is_the_major_axis() -> None:
    assert _record(0.0, False, False, [[0.04, 0.0], [0.0, 0.01]]).position_sigma_m == pytest.approx(0.2)
    # a covariance of eigenvalues 0.05 and 0.01 along the diagonals
    assert _record(0.0, False, False, [[0.03, 0.02], [0.02, 0.03]]).position_sigma_m == pytest.approx(math.sqrt(0.05))
