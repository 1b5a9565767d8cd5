"""A multi-view detector's recall, learnt from the tracks: misses count once the person is shown to have been there."""

from __future__ import annotations

import numpy as np
import pytest

from resource_manager.track.model import TrackModel
from resource_manager.track.motion import MotionModel
from resource_manager.track.recall import MAX_RECALL, PRIOR_S, SharedRecall, detector_misses

MODEL = TrackModel()
GROUPS = {"mv": np.array([0, 1])}
"""Views 0 and 1 are one multi-view detector's; view 2 is a camera with its own."""
SEES = np.ones((3, 1), dtype=bool)
SURE = np.ones(1, dtype=bool)


def _tick(rec: SharedRecall, found: bool, *, other: bool = False, sure: bool = True, dt_s: float = 0.5) -> None:
    """One tick of one track (serial 1): the multi-view detector found it (in its first view) or not; ``other``: the
    camera with its own detector did."""
    got = np.array([[found], [False], [other]])
    rec.learn(GROUPS, SEES, got, sure=np.array([sure]), serials=[1], dt_s=dt_s)


def test_before_any_evidence_a_detector_finds_people_at_p_detect() -> None:
    rec = SharedRecall(MODEL)
    assert rec.recall("mv") == pytest.approx(MODEL.p_detect)
    assert rec.learnt() == {}


def test_a_detector_that_always_finds_the_people_tracked_surely_is_learnt_near_sure() -> None:
    rec = SharedRecall(MODEL)
    for _ in range(400):  # 200 s
        _tick(rec, True)
    expected = (200.0 + PRIOR_S * MODEL.p_detect) / (200.0 + PRIOR_S)
    assert rec.recall("mv") == pytest.approx(min(expected, MAX_RECALL), rel=0.01)
    assert rec.recall("mv") > 0.99


def test_misses_count_only_once_the_person_is_found_again() -> None:
    rec = SharedRecall(MODEL)
    for _ in range(100):
        _tick(rec, True)
    before = rec.recall("mv")
    _tick(rec, False)
    _tick(rec, False)
    assert rec.recall("mv") == pytest.approx(before, rel=1e-3)  # not yet known to be misses: they may have left
    _tick(rec, True)
    assert rec.recall("mv") < before - 0.015  # found again where tracked: two ticks of misses
    # A person whom another detector shows there was missed by this one at once.
    after = rec.recall("mv")
    _tick(rec, False, other=True)
    assert rec.recall("mv") < after


def test_the_misses_of_someone_who_walked_away_never_count() -> None:
    rec = SharedRecall(MODEL)
    for _ in range(100):
        _tick(rec, True)
    before = rec.recall("mv")
    for _ in range(10):  # no longer sure it is someone: its person left unseen
        _tick(rec, False)
    rec.learn(GROUPS, np.zeros((3, 0), dtype=bool), np.zeros((3, 0), dtype=bool), sure=np.zeros(0, dtype=bool),
              serials=[], dt_s=0.5)  # fmt: skip
    assert rec.recall("mv") >= before - 1e-3


def test_a_track_its_misses_ended_counts_them_when_someone_new_appears_where_it_would_be() -> None:
    motion = MotionModel(MODEL.speed_sigma_mps, MODEL.turn_time_s)

    def after_newcomer(at: tuple[float, float]) -> float:
        rec = SharedRecall(MODEL)
        for _ in range(100):
            _tick(rec, True)
        _tick(rec, False)
        x, p = np.array([4.0, 3.0, 1.0, 0.0]), np.diag([0.01, 0.01, 0.1, 0.1])
        rec.ended(1, x, p, t_ns=10**10)
        rec.found(np.array([at]), np.eye(2)[None] * 0.01, t_ns=10**10 + 5 * 10**8, motion=motion)
        return rec.recall("mv")

    base = SharedRecall(MODEL)
    for _ in range(100):
        _tick(base, True)
    assert after_newcomer((4.5, 3.0)) < base.recall("mv") - 0.004  # where the track walked on to: it was there
    assert after_newcomer((1.0, 1.0)) == pytest.approx(base.recall("mv"), rel=1e-4)  # someone else, elsewhere


def test_a_camera_with_its_own_detector_learns_nothing_here() -> None:
    rec = SharedRecall(MODEL)
    rec.learn({}, np.ones((2, 1), dtype=bool), np.zeros((2, 1), dtype=bool), sure=SURE, serials=[1], dt_s=0.5)
    assert rec.recall("") == pytest.approx(MODEL.p_detect)


def test_a_shared_detectors_views_miss_a_person_once_and_not_at_all_when_one_found_them() -> None:
    """Three views of one shared detector, four people: found by view 1 (the other views' misses say nothing); found
    by none while views 0 and 2 should see them (one miss, on view 0); found by none, only view 2 should see them (the
    miss on view 2); nobody should see them (nothing)."""
    ln_miss = np.array(
        [
            [-2.3, -2.3, 0.0, 0.0],
            [0.0, 0.0, 0.0, 0.0],
            [-1.2, -1.2, -0.7, 0.0],
        ]
    )
    got = np.zeros((3, 4), dtype=bool)
    got[1, 0] = True
    once = np.array([-5.0, -5.0, -5.0, -5.0])
    np.testing.assert_array_equal(
        detector_misses(ln_miss, got, once),
        [[0.0, -5.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0], [0.0, 0.0, -5.0, 0.0]],
    )
