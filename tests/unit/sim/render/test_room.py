"""The room: rays hit the floor, ceiling and walls at the distances geometry gives; textures come from the seed."""

from __future__ import annotations

import math

import msgspec
import numpy as np
import pytest

from common.site import CameraSpec, SiteConfig, SiteSection, WorldSpec
from sim.render.room import RoomTextures, cast_room, make_textures
from sim.world import World

FLOOR, CEILING, WALL = (0, 0, 200), (200, 0, 0), (0, 200, 0)


def _flat_room(x_m: float = 8.0, y_m: float = 6.0, h_m: float = 3.0) -> RoomTextures:
    def tex(h: int, w: int, bgr: tuple[int, int, int]) -> np.ndarray:
        return np.full((h, w, 3), bgr, np.uint8)

    return RoomTextures(
        floor=tex(300, 400, FLOOR), ceiling=tex(300, 400, CEILING), walls=tex(150, 1400, WALL),
        room_x_m=x_m, room_y_m=y_m, wall_height_m=h_m,
    )  # fmt: skip


@pytest.mark.parametrize(
    ("bearing", "slope", "depth_m", "bgr"),
    [
        (0.0, 0.0, 6.0, WALL),  # level, towards the wall x = 8
        (math.pi / 2, 0.0, 3.0, WALL),  # towards y = 6
        (math.pi, 0.1, 2.0, WALL),  # slightly up, towards x = 0: the wall before the ceiling
        (math.pi, -1.0, 1.0, FLOOR),  # 45 deg down from 1 m up: the floor 1 m away
        (0.0, 1.0, 2.0, CEILING),  # 45 deg up from 1 m under a 3 m ceiling
        (-math.pi / 2, -0.25, 3.0, WALL),  # towards y = 0, 3 m away; would hit the floor at 4 m
    ],
)
def test_a_ray_hits_the_first_surface_on_its_way(
    bearing: float, slope: float, depth_m: float, bgr: tuple[int, int, int]
) -> None:
    img, depth = cast_room(
        _flat_room(), (2.0, 3.0, 1.0), np.array([math.cos(bearing)]), np.array([math.sin(bearing)]), np.array([slope])
    )
    assert float(depth.ravel()[0]) == pytest.approx(depth_m, rel=1e-5)
    assert img.reshape(-1, 3)[0].tolist() == list(bgr)


def test_panorama_rays_broadcast_columns_against_rows() -> None:
    cols = np.linspace(-math.pi, math.pi, 16, endpoint=False)[None, :]
    slopes = np.array([[-0.5], [0.0], [0.5]])
    img, depth = cast_room(_flat_room(), (4.0, 3.0, 1.0), np.cos(cols), np.sin(cols), slopes)
    assert img.shape == (3, 16, 3) and depth.shape == (3, 16)
    assert depth[0] == pytest.approx(np.full(16, 2.0)) and (img[0] == FLOOR).all()  # 1 m down at slope -0.5: 2 m out
    assert (depth[1] >= 3.0 - 1e-6).all() and (img[1] == WALL).all()


def _world(seed: int) -> World:
    spec = msgspec.convert({"room_x_m": 5.0, "room_y_m": 4.0, "people": 0}, WorldSpec)
    return World.from_site(
        SiteConfig(site=SiteSection(name="t", seed=seed), world=spec, camera=[CameraSpec(id="c", x_m=2.0, y_m=2.0)])
    )


def test_textures_cover_the_room_and_depend_on_the_seed() -> None:
    a, b, c = make_textures(_world(1)), make_textures(_world(1)), make_textures(_world(2))
    assert (a.room_x_m, a.room_y_m) == (5.0, 4.0)
    assert np.array_equal(a.walls, b.walls) and np.array_equal(a.floor, b.floor)
    assert not np.array_equal(a.walls, c.walls)
    assert a.walls.std() > 5.0  # textured, not flat paint: background subtraction has something to model
