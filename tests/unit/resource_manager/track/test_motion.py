"""The motion model and the robust update: prediction, and bearings pulling a prior onto a person."""

from __future__ import annotations

import math

import numpy as np
import pytest

from resource_manager.track.motion import (
    IEKF_ITERATIONS,
    LineObservation,
    MotionModel,
    Observation,
    ObservationBatch,
    predict,
    update,
    update_many,
    update_without_each,
)


def test_an_unseen_walker_is_predicted_to_stop_and_spread_like_a_random_walk() -> None:
    """The velocity decays over ``turn_time_s``: a walker unseen for long ends near where they were heading
    (τ·v further), and the position variance then grows about linearly in time, not with t³."""
    m = MotionModel(speed_sigma_mps=0.8, turn_time_s=2.0)
    x0, p0 = np.array([0.0, 0.0, 1.0, 0.0]), np.diag([0.01, 0.01, 0.01, 0.01])
    far, pf = predict(x0, p0, 30.0, m)
    assert far[0] == pytest.approx(2.0, abs=1e-6) and abs(far[2]) < 1e-6  # stopped τ·v = 2 m on
    _, p10 = predict(x0, p0, 10.0, m)
    _, p20 = predict(x0, p0, 20.0, m)
    growth = (pf[0, 0] - p20[0, 0]) / (p20[0, 0] - p10[0, 0])
    assert growth == pytest.approx(1.0, abs=0.1)  # 10 s more adds as much as the 10 s before: diffusion
    near, _ = predict(x0, p0, 0.1, m)
    assert near[0] == pytest.approx(0.1, abs=0.005)  # a frame later: still walking at 1 m/s
    same, same_p = predict(x0, p0, 0.0, m)
    assert same is x0 and same_p is p0


def _bearing(origin: tuple[float, float], xy: tuple[float, float], var: float = 1e-5) -> Observation:
    return Observation(origin, math.atan2(xy[1] - origin[1], xy[0] - origin[0]), var)


def test_bearings_from_three_cameras_pull_a_wide_prior_onto_the_person() -> None:
    person = (3.0, 4.0)
    x, p = np.array([4.5, 2.5, 0.0, 0.0]), np.diag([1.0, 1.0, 0.5, 0.5])
    obs = [_bearing(o, person) for o in ((0.0, 0.0), (8.0, 0.0), (0.0, 8.0))]
    xn, pn, w = update(x, p, obs)
    assert float(np.hypot(xn[0] - 3.0, xn[1] - 4.0)) < 0.01
    assert pn[0, 0] < 0.001 and pn[1, 1] < 0.001 and np.all(w == 1.0)


def test_fewer_gauss_newton_steps_stop_short_of_the_bearings_meeting_point() -> None:
    """Bearings re-linearised at each step: one step (the plain EKF update) from a prior 1.5 m off lands short of
    where the views' rays meet, the default iterations on it."""
    person = (3.0, 4.0)
    x, p = np.array([4.5, 2.5, 0.0, 0.0]), np.diag([1.0, 1.0, 0.5, 0.5])
    batch = ObservationBatch.of([[_bearing(o, person) for o in ((0.0, 0.0), (8.0, 0.0), (0.0, 8.0))]], [[]])
    off = {}
    for n in (1, 2, IEKF_ITERATIONS):
        xn, _, _ = update_many(x[None], p[None], batch, iterations=n)
        off[n] = float(np.hypot(xn[0, 0] - person[0], xn[0, 1] - person[1]))
    default, _, _ = update_many(x[None], p[None], batch)
    assert off[1] > 0.01 and off[IEKF_ITERATIONS] < 0.01 and off[2] < off[1]
    assert float(np.hypot(*(default[0, :2] - person))) == pytest.approx(off[IEKF_ITERATIONS])


def test_each_view_left_out_is_the_update_of_the_others() -> None:
    """Four views that disagree by a few centimetres (bearings and floor distances): the full update with each
    view's information taken out again lands where updating with the other three lands (within a few mm, while
    leaving a view out moves the estimate by centimetres); a track's only view left out gives back its prior."""
    rng = np.random.default_rng(3)
    cams = ((0.0, 0.0), (8.0, 0.0), (0.0, 8.0), (8.0, 8.0))
    x, p = np.array([3.3, 3.8, 0.2, 0.0]), np.diag([0.2, 0.2, 0.3, 0.3])
    obs = []
    for c in cams:
        seen = (3.0 + rng.normal(0.0, 0.1), 4.0 + rng.normal(0.0, 0.1))
        b = _bearing(c, seen, 4e-4)
        obs.append(Observation(c, b.bearing_rad, b.bearing_var, math.dist(c, seen), 0.04))
    batch = ObservationBatch.of([obs, obs[1:2]], [[], []])
    full, p_full, out, p_out = update_without_each(np.stack([x, x]), np.stack([p, p]), batch, (0.05, 4.0))
    moved = []
    for v in range(len(cams)):
        rest, p_rest, _ = update_many(
            x[None], p[None], ObservationBatch.of([obs[:v] + obs[v + 1 :]], [[]]), (0.05, 4.0)
        )
        assert float(np.hypot(*(out[0, v, :2] - rest[0, :2]))) < 0.005
        assert np.abs(p_out[0, v, :2, :2] - p_rest[0, :2, :2]).max() < 0.05 * np.trace(p_rest[0, :2, :2])
        moved.append(float(np.hypot(*(rest[0, :2] - full[0, :2]))))
    assert max(moved) > 0.02
    assert out[1, 0] == pytest.approx(x) and p_out[1, 0] == pytest.approx(p)
    assert np.trace(p_full[1, :2, :2]) < np.trace(p[:2, :2])  # the view itself did count


def test_one_wrong_view_is_down_weighted_by_the_others() -> None:
    """Three views agree on the person; a fourth gave another person's blob (3 m off): with the outlier
    component the estimate stays on the person and that view's weight falls; without, it is dragged off."""
    person = (3.0, 4.0)
    good = [_bearing(o, person) for o in ((0.0, 0.0), (8.0, 0.0), (0.0, 8.0))]
    wrong = _bearing((8.0, 8.0), (6.0, 4.0))
    x, p = np.array([3.2, 3.8, 0.0, 0.0]), np.diag([0.25, 0.25, 0.5, 0.5])
    robust, _, w = update(x, p, [*good, wrong], (0.05, 4.0))
    plain, _, _ = update(x, p, [*good, wrong])
    assert float(np.hypot(robust[0] - 3.0, robust[1] - 4.0)) < 0.02
    assert float(np.hypot(plain[0] - 3.0, plain[1] - 4.0)) > 0.1
    assert w[3] < 0.1 and np.all(w[:3] > 0.9)


def test_a_wrong_size_ratio_line_is_down_weighted_by_the_views() -> None:
    """Two views agree on the person; a size-ratio fix along their baseline says 1 m further (one blob's width
    cut by someone in front): with the outlier component the views keep the estimate; without, the line drags it."""
    person = (3.0, 4.0)
    good = [_bearing(o, person, 1e-4) for o in ((0.0, 0.0), (8.0, 0.0))]  # about 0.6°
    wrong = LineObservation(direction=(0.0, 1.0), value=5.0, var=0.01)
    x, p = np.array([3.1, 4.1, 0.0, 0.0]), np.diag([0.25, 0.25, 0.5, 0.5])
    robust, _, _ = update(x, p, good, (0.05, 4.0), lines=[wrong])
    plain, _, _ = update(x, p, good, lines=[wrong])
    assert float(np.hypot(robust[0] - 3.0, robust[1] - 4.0)) < 0.05
    assert float(np.hypot(plain[0] - 3.0, plain[1] - 4.0)) > 0.1
    agree = LineObservation(direction=(0.0, 1.0), value=4.0, var=0.01)
    kept, pk, _ = update(x, p, good[:1], (0.05, 4.0), lines=[agree])
    assert float(np.hypot(kept[0] - 3.0, kept[1] - 4.0)) < 0.05 and pk[1, 1] < 0.02  # a line that agrees counts
