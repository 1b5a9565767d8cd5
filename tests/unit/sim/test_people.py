"""People's looks and the door: drawn from (seed, person) alone, distinct shirts, within the configured ranges."""

from __future__ import annotations

import msgspec
import pytest

from common.site import WorldSpec
from sim.people import Door, make_look


def _spec(**world: object) -> WorldSpec:
    return msgspec.convert({"people": 20, **world}, WorldSpec)


def test_a_look_depends_on_seed_and_person_only() -> None:
    spec = _spec()
    assert make_look(spec, 7, 3) == make_look(spec, 7, 3)
    assert make_look(spec, 7, 3) != make_look(spec, 8, 3)
    assert make_look(spec, 7, 3).person_id == 4  # ids count from 1


@pytest.mark.parametrize(("height", "speed"), [((1.5, 1.9), (0.5, 1.5)), ((1.7, 1.72), (1.0, 1.01))])
def test_heights_and_speeds_stay_in_the_configured_ranges(
    height: tuple[float, float], speed: tuple[float, float]
) -> None:
    spec = _spec(person_height_m=list(height), person_speed_mps=list(speed))
    looks = [make_look(spec, 1, i) for i in range(spec.people)]
    assert all(height[0] <= look.height_m <= height[1] for look in looks)
    assert all(speed[0] <= look.speed_mps <= speed[1] for look in looks)


def test_shirts_differ_and_are_never_the_robots_white() -> None:
    spec = _spec(people=30)
    shirts = [make_look(spec, 2, i).shirt_rgb for i in range(spec.people)]
    assert len(set(shirts[:16])) == 16  # the palette's worth of people: all different
    assert len(set(shirts)) == 30  # beyond it, shades of the palette: still all different
    assert all(min(rgb) < 200 for rgb in shirts)


def test_the_door_points_lie_either_side_of_the_wall_in_front_of_the_gap() -> None:
    door = Door(x0_m=1.0, x1_m=2.0)
    (xi, yi), (xo, yo) = door.inside_xy, door.outside_xy
    assert door.x0_m < xi < door.x1_m and door.x0_m < xo < door.x1_m
    assert yi > 0.0 > yo  # the wall is y = 0, the room y > 0
