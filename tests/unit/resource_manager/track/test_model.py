"""The tracker's model: log-odds and the motion model's turn rate."""

from __future__ import annotations

import math

import pytest

from resource_manager.track.model import TrackModel, logit


@pytest.mark.parametrize(("p", "expected"), [(0.5, 0.0), (0.9, math.log(9.0)), (0.1, -math.log(9.0))])
def test_logit(p: float, expected: float) -> None:
    assert logit(p) == pytest.approx(expected)


def test_defaults_let_a_born_track_be_confirmed_and_a_confirmed_one_end() -> None:
    m = TrackModel()
    assert m.p_delete <= m.p_birth < m.p_confirm < m.p_max < 1.0
    assert TrackModel(turn_time_s=4.0).turn_rate == pytest.approx(0.25)
