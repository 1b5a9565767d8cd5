"""The site's floor area: inside tests, distances to exits, and clear errors for bad polygons."""

from __future__ import annotations

import numpy as np
import pytest

from common.area import Area, AreaSpec, NearZone, overlap_m2, rectangle, signed_depth
from common.errors import ConfigError

L_SHAPE = [[0.0, 0.0], [4.0, 0.0], [4.0, 2.0], [2.0, 2.0], [2.0, 4.0], [0.0, 4.0]]


@pytest.mark.parametrize(
    ("xy", "inside"),
    [((1.0, 1.0), True), ((3.0, 1.0), True), ((1.0, 3.0), True), ((3.0, 3.0), False), ((-0.1, 1.0), False)],
)
def test_contains_follows_a_concave_polygon(xy: tuple[float, float], inside: bool) -> None:
    area = Area.of(AreaSpec(polygon=L_SHAPE))
    assert bool(area.contains(np.array([xy]))[0]) is inside


def test_exits_default_to_the_whole_boundary_and_narrow_when_declared() -> None:
    everywhere = Area.of(AreaSpec(polygon=L_SHAPE))
    door = Area.of(AreaSpec(polygon=L_SHAPE, exits=[[[0.0, 1.0], [0.0, 2.0]]]))
    p = np.array([[3.5, 1.0], [0.5, 1.5]])
    np.testing.assert_allclose(everywhere.exit_distance(p), [0.5, 0.5])
    np.testing.assert_allclose(door.exit_distance(p), [3.5, 0.5])
    np.testing.assert_allclose(door.boundary_distance(p), [0.5, 0.5])


def test_an_exit_polygon_counts_by_its_edges() -> None:
    area = Area.of(AreaSpec(polygon=L_SHAPE, exits=[[[3.0, -0.5], [4.5, -0.5], [4.5, 0.5], [3.0, 0.5]]]))
    assert area.exit_distance(np.array([[3.5, 0.2]]))[0] == pytest.approx(0.3)


@pytest.mark.parametrize(
    ("polygon", "exits", "says"),
    [
        ([[0.0, 0.0], [1.0, 0.0]], [], "at least 3 corners"),
        ([[0.0, 0.0], [2.0, 2.0], [2.0, 0.0], [0.0, 2.0]], [], "not simple"),
        ([[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]], [], "encloses no area"),
        ([[0.0, 0.0], [1.0, 0.0], [0.0, float("nan")]], [], "finite"),
        ([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]], [[[0.0, 0.0]]], "exits[0]"),
    ],
)
def test_a_bad_area_is_named(polygon: list[list[float]], exits: list[list[list[float]]], says: str) -> None:
    with pytest.raises(ConfigError, match=says.replace("[", r"\[").replace("]", r"\]")):
        Area.of(AreaSpec(polygon=polygon, exits=exits))


def test_rectangle_checks_its_corners() -> None:
    assert Area.of(rectangle(0.0, 0.0, 2.0, 1.0)).area_m2 == pytest.approx(2.0)
    with pytest.raises(ConfigError, match="X0 < X1"):
        rectangle(2.0, 0.0, 0.0, 1.0)


@pytest.mark.parametrize(
    ("b", "shared"),
    [
        (rectangle(10.0, 0.0, 20.0, 10.0), 0.0),  # a shared border is no shared floor
        (rectangle(10.0, 10.0, 20.0, 20.0), 0.0),  # nor a shared corner
        (rectangle(5.0, 5.0, 15.0, 15.0), 25.0),
        (rectangle(0.0, 0.0, 10.0, 10.0), 100.0),
        (rectangle(2.0, 2.0, 3.0, 3.0), 1.0),  # inside, touching no edge
    ],
)
def test_overlap_of_two_squares(b: AreaSpec, shared: float) -> None:
    a = Area.of(rectangle(0.0, 0.0, 10.0, 10.0))
    assert overlap_m2(a, Area.of(b)) == pytest.approx(shared, abs=1e-9)
    assert overlap_m2(Area.of(b), a) == pytest.approx(shared, abs=1e-9)


def test_overlap_of_a_concave_polygon_counts_only_its_floor() -> None:
    """An L (36 m², clockwise) and a square over its notch: only the L's arms are shared."""
    ell = Area.of(AreaSpec(polygon=[[0, 10], [2, 10], [2, 2], [10, 2], [10, 0], [0, 0]]))
    assert overlap_m2(ell, ell) == pytest.approx(36.0)
    assert overlap_m2(ell, Area.of(rectangle(3.0, 3.0, 9.0, 9.0))) == pytest.approx(0.0, abs=1e-9)
    assert overlap_m2(ell, Area.of(rectangle(1.0, 1.0, 9.0, 9.0))) == pytest.approx(8.0 + 7.0)


def test_near_zone_is_the_site_within_a_margin_of_the_zone_and_its_far_edge_an_exit() -> None:
    """A 10 x 10 m site with one door on its west wall, a zone in its east half, followed 2 m beyond."""
    site = Area.of(AreaSpec(polygon=[[0, 0], [10, 0], [10, 10], [0, 10]], exits=[[[0.0, 4.0], [0.0, 6.0]]]))
    zone = Area.of(rectangle(5.0, 0.0, 10.0, 10.0))
    near = NearZone(zone, 2.0, site)
    xy = np.array([[7.0, 5.0], [3.5, 5.0], [2.5, 5.0], [11.0, 5.0]])
    assert near.contains(xy).tolist() == [True, True, False, False]  # in, in the margin, beyond it, off the site
    np.testing.assert_allclose(signed_depth(zone, xy[:3]), [2.0, -1.5, -2.5])
    # the margin's far edge (x = 3) is an exit, the site's walls are not (only its door)
    np.testing.assert_allclose(near.exit_distance(np.array([[3.5, 5.0], [9.5, 5.0]])), [0.5, 6.5])
    np.testing.assert_allclose(near.boundary_distance(np.array([[3.5, 5.0], [9.5, 5.0]])), [0.5, 0.5])
    assert near.bounds == (3.0, 0.0, 10.0, 10.0)
    assert near.area_m2 == pytest.approx(70.0, rel=0.02)


def test_near_zone_without_a_site_area_lets_people_come_and_go_anywhere() -> None:
    near = NearZone(Area.of(rectangle(0.0, 0.0, 4.0, 4.0)), 1.0)
    assert near.contains(np.array([[4.9, 2.0], [5.1, 2.0]])).tolist() == [True, False]
    np.testing.assert_allclose(near.exit_distance(np.array([[2.0, 2.0]])), [0.0])
    assert near.bounds == (-1.0, -1.0, 5.0, 5.0)
