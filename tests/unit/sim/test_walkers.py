"""The crowd simulation on its own: people stay in the room, clear of platforms, and sampling is repeatable."""

from __future__ import annotations

import itertools
import math

import msgspec
import numpy as np
import pytest

from common.errors import ConfigError
from common.site import WorldSpec
from sim.people import Door
from sim.walkers import MAX_CATCH_UP_S, WalkerSim

DOOR = Door(x0_m=1.0, x1_m=2.0)
POST = (4.0, 3.0, 0.4)


def _sim(seed: int = 1, **world: object) -> WalkerSim:
    spec = msgspec.convert({"room_x_m": 8.0, "room_y_m": 6.0, "people": 4, **world}, WorldSpec)
    return WalkerSim(spec, seed, lambda _t: [POST], DOOR)


def _track(sim: WalkerSim, t_end_s: float, dt_s: float) -> list:
    return [sim.sample(float(t)) for t in np.arange(0.0, t_end_s, dt_s)]


@pytest.mark.parametrize("paths", ["random", "line"])
def test_walkers_stay_in_the_room_and_clear_of_a_platform(paths: str) -> None:
    sim = _sim(paths=paths, rectangle=[1.0, 1.0, 7.0, 1.0])
    for s in _track(sim, 40.0, 0.25):
        assert s.present.all()
        assert (s.x_m > 0.0).all() and (s.x_m < 8.0).all() and (s.y_m > 0.0).all() and (s.y_m < 6.0).all()
        assert (np.hypot(s.x_m - POST[0], s.y_m - POST[1]) >= POST[2] + 0.25).all()


def test_people_entering_and_leaving_go_through_the_door() -> None:
    samples = _track(_sim(enter_leave=True, people=4), 120.0, 0.1)
    present = np.array([s.present for s in samples])
    assert (~present).any(axis=0).sum() >= 2  # some are outside for a while
    assert present.any(axis=0).all()  # and everyone is in at some point
    for a, b in itertools.pairwise(samples):
        crossing = a.present != b.present
        for i in np.flatnonzero(crossing):
            x = (a.x_m[i] + b.x_m[i]) / 2
            assert DOOR.x0_m - 0.3 <= x <= DOOR.x1_m + 0.3  # in or out at the door, not through the wall


def test_sampling_again_or_out_of_order_gives_the_same_states() -> None:
    a, b = _sim(seed=5), _sim(seed=5)
    late = a.sample(33.3)
    early = a.sample(2.0)  # back in time after simulating ahead
    assert b.sample(2.0).x_m == pytest.approx(early.x_m)
    assert b.sample(33.3).x_m == pytest.approx(late.x_m)
    a.invalidate_from(10.0)  # same obstacles: recomputing gives the same crowd
    assert a.sample(33.3).y_m == pytest.approx(late.y_m)
    assert not np.allclose(_sim(seed=6).sample(33.3).x_m, late.x_m)


def test_samples_between_steps_are_interpolated() -> None:
    sim = _sim()
    a, mid, b = sim.sample(10.0), sim.sample(10.025), sim.sample(10.05)
    assert mid.x_m == pytest.approx((a.x_m + b.x_m) / 2)
    assert all(math.isfinite(v) for v in mid.heading_rad)


def test_a_time_far_beyond_the_simulation_means_a_wrong_epoch() -> None:
    with pytest.raises(ConfigError, match="epoch"):
        _sim().sample(MAX_CATCH_UP_S + 100.0)
