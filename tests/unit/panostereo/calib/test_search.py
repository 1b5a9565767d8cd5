"""A camera far from its guess found again against an anchor's people."""

from __future__ import annotations

import math

import numpy as np

from panostereo.calib.adjust import Tolerance
from panostereo.calib.associate import HeightPrior
from panostereo.calib.poses import pose_change
from panostereo.calib.search import anchor_people, find_pose, support
from tests.unit.panostereo.calib.test_associate import _rays


def _tracks(n_people: int, n_instants: int) -> np.ndarray:
    """(instants, people, 3): people walking straight lines across the square."""
    rng = np.random.default_rng(1)
    start = rng.uniform(3, 9, size=(n_people, 2))
    step = rng.normal(size=(n_people, 2))
    step *= 0.6 / np.linalg.norm(step, axis=1, keepdims=True)
    out = np.empty((n_instants, n_people, 3))
    for k in range(n_instants):
        out[k, :, :2] = start + k * step
        out[k, :, 2] = 1.75
    return out


def _camera(cid: str, paths: np.ndarray):  # type: ignore[no-untyped-def]
    rays, pose = _rays(cid, paths.reshape(-1, 3))
    n_inst, n_people = paths.shape[:2]
    fields = {f: getattr(rays, f) for f in rays.__slots__}
    fields["instant"] = np.repeat(np.arange(n_inst, dtype=np.int64), n_people)
    fields["track"] = np.tile(np.arange(n_people, dtype=np.int64), n_inst)
    return type(rays)(**fields), pose


def test_a_camera_turned_15_deg_and_moved_1_5_m_is_found() -> None:
    paths = _tracks(5, 8)
    (a, a_pose), (b, b_pose) = _camera("cam-a", paths), _camera("cam-b", paths)
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    guess = b_pose.turned_moved(axis * math.radians(15.0), [1.5, 0.0, 0.0])
    people = anchor_people([a, b], [a_pose, guess], [0], HeightPrior(), 100.0)
    found = find_pose(b, guess, people, Tolerance(), 0.5)
    assert found.score > found.start_score and found.hypotheses > 0
    moved, turned = pose_change(b_pose, found.pose)
    assert moved < 0.05 and math.degrees(turned) < 0.3
    assert support(b, found.pose, people, 0.5) == found.score


def test_no_better_hypothesis_keeps_the_guess() -> None:
    paths = _tracks(5, 8)
    (a, a_pose), (b, b_pose) = _camera("cam-a", paths), _camera("cam-b", paths)
    people = anchor_people([a, b], [a_pose, b_pose], [0], HeightPrior(), 100.0)
    found = find_pose(b, b_pose, people, Tolerance(), 0.5)
    assert found.score == found.start_score


def test_track_pairs_keep_every_pair_a_pose_within_the_window_explains() -> None:
    """A pair is left out before its pose is worked out only where no pose within the window of the guess can see
    the anchor's person along the camera's rays: the true pairs stay for guesses anywhere in the window, and a
    person the camera would have to see behind it goes."""
    from panostereo.calib.search import AnchorPeople, _track_pairs

    paths = _tracks(5, 8)
    (a, a_pose), (b, b_pose) = _camera("cam-a", paths), _camera("cam-b", paths)
    people = anchor_people([a, b], [a_pose, b_pose], [0], HeightPrior(), 100.0)
    tol = Tolerance()
    window = (2.0 * tol.centre_m, 2.0 * tol.turn_rad)
    truth = {(t, t * 1000) for t in range(5)}
    rng = np.random.default_rng(2)
    for _ in range(200):
        axis = rng.normal(size=3)
        shift = rng.normal(size=3)
        # Up to the window's edge: turned and moved by as much as the search looks.
        guess = b_pose.turned_moved(
            axis / np.linalg.norm(axis) * window[1] * rng.uniform(0.5, 1.0),
            shift / np.linalg.norm(shift) * window[0] * rng.uniform(0.5, 1.0),
        )
        assert truth <= set(_track_pairs(b, people, guess, window, 0.5)), guess
    # The anchor's person 0 put where camera b would have to look back over its shoulder to see them.
    behind = people.point.copy()
    mine = people.track == 0
    behind[mine, :2] = 2.0 * b_pose.centre_m[:2] - behind[mine, :2]
    turned = AnchorPeople(people.instant, people.track, behind)
    pairs = set(_track_pairs(b, turned, b_pose, window, 0.5))
    assert (0, 0) not in pairs and {(t, t * 1000) for t in range(1, 5)} <= pairs
