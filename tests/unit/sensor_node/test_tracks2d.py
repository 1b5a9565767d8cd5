"""2D tracks: stable local ids, across the seam, new ids for newcomers, expiry, predicted heads."""

from __future__ import annotations

import pytest

from sensor_node.tracks2d import Tracker2D


def test_ids_follow_moving_blobs_and_cross_the_seam() -> None:
    tr = Tracker2D(gate=20.0, max_missed=2, period=1080.0)
    a, b = tr.update([(1070.0, 40.0), (300.0, 50.0)])
    assert a != b
    for k in range(1, 6):
        ids = tr.update([(300.0 - 4 * k, 50.0), ((1070.0 + 5 * k) % 1080, 40.0)])
        assert ids == [b, a]


def test_newcomer_and_expiry() -> None:
    tr = Tracker2D(gate=10.0, max_missed=1)
    (a,) = tr.update([(100.0, 10.0)])
    a2, c = tr.update([(102.0, 10.0), (500.0, 10.0)])
    assert a2 == a and c not in (a,)
    tr.update([])
    tr.update([])
    (d,) = tr.update([(104.0, 10.0)])  # gone for 2 frames > max_missed: a new id
    assert d not in (a, c)
    assert len(tr) == 1


def test_greedy_prefers_the_nearest() -> None:
    tr = Tracker2D(gate=30.0)
    a, b = tr.update([(100.0, 0.0), (120.0, 0.0)])
    assert tr.update([(118.0, 0.0), (101.0, 0.0)]) == [b, a]


def test_predicted_heads_come_from_tracks_seen_standing_alone() -> None:
    tr = Tracker2D(gate=20.0, max_missed=3, period=1080.0)
    for k in range(4):
        tr.update([(100.0 + 2 * k, 50.0), (300.0, 50.0)], [False, True])  # the second one always cut from a group
    assert tr.predicted(4) == [(pytest.approx(108.0, abs=0.5), pytest.approx(50.0))]
    assert len(tr.predicted(0)) == 2
    tr.update([(300.0, 50.0)])  # the first one unseen: still predicted for max_missed frames
    assert [u for u, _ in tr.predicted(4, max_missed=1)] == [pytest.approx(109.5, abs=0.5)]
    assert tr.predicted(4, max_missed=0) == []
