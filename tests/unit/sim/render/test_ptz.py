"""Ray casting bodies into a perspective image: a body shows at the pixel the pinhole model projects, nearer wins."""

from __future__ import annotations

import math

import numpy as np
import pytest

from common.cameras import PtzCamera
from sim.render.bodies import Cylinder, Head
from sim.render.ptz import RayGrid, paint_primitives_rays

W, H = 160, 120


def _grid(pan_rad: float = 0.0, tilt_rad: float = 0.0) -> RayGrid:
    pinhole = PtzCamera(0.0, 0.0, 1.5, W, H, math.radians(60.0), pan_rad, tilt_rad).pinhole()
    vv, uu = np.mgrid[0:H, 0:W].astype(np.float64)
    rays = pinhole.ray_world(np.column_stack([uu.ravel(), vv.ravel()]))
    rho = np.hypot(rays[:, 0], rays[:, 1])
    return RayGrid(
        (0.0, 0.0, 1.5), (rays[:, 0] / rho).reshape(H, W), (rays[:, 1] / rho).reshape(H, W),
        (rays[:, 2] / rho).reshape(H, W), pinhole,
    )  # fmt: skip


def _paint(grid: RayGrid, prims: list, far_m: float = 100.0) -> tuple[np.ndarray, np.ndarray]:
    img = np.zeros((H, W, 3), np.uint8)
    depth = np.full((H, W), far_m, np.float32)
    paint_primitives_rays(img, depth, grid, prims)
    return img, depth


def _channel(bgr: np.ndarray) -> int:
    """The one channel a flat-coloured (shaded) body lights: 0 blue, 1 green, 2 red; -1 for black."""
    return int(np.argmax(bgr)) if bgr.max() > 100 and np.sort(bgr)[-2] == 0 else -1


def _pixel(grid: RayGrid, xyz: tuple[float, float, float]) -> tuple[int, int]:
    uv, ok = grid.pinhole.project(np.array([xyz]))
    assert ok.all()
    return round(float(uv[0, 0])), round(float(uv[0, 1]))


@pytest.mark.parametrize(("pan_rad", "xy"), [(0.0, (4.0, 0.5)), (math.pi / 2, (-0.4, 3.0)), (-2.5, (-3.0, -2.5))])
def test_a_cylinder_shows_where_the_pinhole_model_projects_it_at_its_depth(
    pan_rad: float, xy: tuple[float, float]
) -> None:
    grid = _grid(pan_rad)
    radius_m = 0.25
    img, depth = _paint(grid, [Cylinder(xy[0], xy[1], radius_m, radius_m, 0.0, 0.0, 1.7, ((0.0, (0, 0, 255)),), 1)])
    u, v = _pixel(grid, (xy[0], xy[1], 1.0))
    assert _channel(img[v, u]) == 2
    dist_m = math.hypot(*xy)
    assert depth[v, u] == pytest.approx(dist_m - radius_m, abs=0.02)  # the near surface, horizontal distance
    u_top, v_top = _pixel(grid, (xy[0], xy[1], 1.9))
    assert not img[v_top, u_top].any()  # above its top: not painted
    painted = np.flatnonzero(img[v].any(axis=1))
    f_px = W / 2 / math.tan(math.radians(30.0))
    assert painted.size == pytest.approx(2 * radius_m / dist_m * f_px, rel=0.2)


def test_only_what_is_nearer_than_the_depth_buffer_is_painted() -> None:
    grid = _grid()
    near = Cylinder(2.0, 0.0, 0.2, 0.2, 0.0, 0.0, 1.2, ((0.0, (255, 0, 0)),), 1)
    far = Cylinder(4.0, 0.0, 0.3, 0.3, 0.0, 0.0, 1.9, ((0.0, (0, 255, 0)),), 2)
    u, v = _pixel(grid, (4.0, 0.0, 0.6))  # the ray passes the near one at 1.05 m
    for prims in ([near, far], [far, near]):
        img, _ = _paint(grid, prims)
        assert _channel(img[v, u]) == 0
    u_hi, v_hi = _pixel(grid, (4.0, 0.0, 1.7))
    assert _channel(img[v_hi, u_hi]) == 1  # the far one, above the near one's top (the ray passes at 1.6 m)
    img, _ = _paint(grid, [far], far_m=3.0)  # a wall 3 m away: the body behind it is hidden
    assert not img.any()


def test_a_head_facing_the_camera_shows_its_face_under_its_hair() -> None:
    grid = _grid()
    img, _ = _paint(grid, [Head(3.0, 0.0, 1.5, 0.1, 0.13, math.pi, (150, 170, 200), (10, 10, 10), 4)])
    u, v = _pixel(grid, (3.0, 0.0, 1.5))
    assert img[v, u, 2] > 100  # skin where the face is
    _, v_crown = _pixel(grid, (3.0, 0.0, 1.61))
    assert img[v_crown, u].max() < 30  # hair on top
