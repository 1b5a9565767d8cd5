"""The one owner of every track's state: rows added and kept, prediction, fixes, existence held below caps."""

from __future__ import annotations

import numpy as np
import pytest

from resource_manager.track.filter import TrackFilter
from resource_manager.track.motion import MotionModel


def _filter(n: int = 2) -> TrackFilter:
    f = TrackFilter(MotionModel(0.8, 2.0), height_change_mps=0.05)
    x = np.array([[float(k), 0.0, 1.0, 0.0] for k in range(n)])
    p = np.repeat(np.eye(4)[None] * 0.01, n, axis=0)
    f.add(x, p, height=np.full(n, 1.7), height_var=np.full(n, 0.01), logodds=np.arange(n, dtype=float), t_ns=0)
    return f


def test_rows_are_added_kept_in_order_and_remember_where_they_were_seen() -> None:
    f = _filter(3)
    assert f.n == 3 and list(f.logodds) == [0.0, 1.0, 2.0]
    f.predict(1_000_000_000)
    f.mark_seen(np.array([1]))
    f.keep(np.array([2, 1]))
    assert f.n == 2 and list(f.logodds) == [2.0, 1.0]
    assert f.seen_x[1, 0] == pytest.approx(f.x[1, 0])  # seen after the prediction
    assert f.seen_x[0, 0] == pytest.approx(2.0)  # never seen since it was added


def test_prediction_moves_and_widens_every_track_to_the_instant() -> None:
    f = _filter(1)
    gaps = f.predict(500_000_000)
    assert gaps.tolist() == [0.5] and list(f.t_ns) == [500_000_000]
    assert 0.3 < f.x[0, 0] < 0.5  # walking at 1 m/s, the velocity slowly decaying
    assert f.p[0, 0, 0] > 0.01 and f.height_var[0] > 0.01


def test_a_fix_pulls_a_track_towards_it_by_the_two_covariances() -> None:
    f = _filter(1)
    f.fix(0, np.array([1.0, 0.0]), np.eye(2) * 0.01)
    assert f.x[0, 0] == pytest.approx(0.5) and f.p[0, 0, 0] == pytest.approx(0.005)


def test_existence_moves_view_after_view_only_where_a_view_sees_and_stays_below_its_cap() -> None:
    f = _filter(2)
    delta = np.array([[3.0, -2.0], [3.0, -2.0]])
    f.existence_update(delta, np.array([1.0, 0.5]), np.array([[True, True], [True, False]]), np.array([4.0, 10.0]))
    assert f.logodds.tolist() == pytest.approx([4.0, -1.0])  # held at its cap; one view of the second counts
    assert f.existence()[0] == pytest.approx(1.0 / (1.0 + np.exp(-4.0)))
