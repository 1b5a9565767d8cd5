"""Painting into a cylindrical panorama: each body lands where the camera model projects it, near over far."""

from __future__ import annotations

import math

import numpy as np
import pytest

from common.cameras import CylindricalCamera
from sim.render.bodies import Cylinder, Head
from sim.render.panoramic import PanoView, paint_primitives

CAM = CylindricalCamera(width_px=720, height_px=200, f_v_px=120.0, v0_px=100.0, height_m=1.0)
RED = ((0.0, (0, 0, 255)),)
BLUE = ((0.0, (255, 0, 0)),)


def _paint(view: PanoView, prims: list) -> tuple[np.ndarray, np.ndarray]:
    pano = np.zeros((CAM.height_px, CAM.width_px, 3), np.uint8)
    labels = np.zeros(pano.shape[:2], np.int32)
    paint_primitives(pano, CAM, view, prims, labels)
    return pano, labels


@pytest.mark.parametrize(
    ("view", "xy"),
    [
        (PanoView(0.0, 0.0, 1.0, 0.0), (2.0, 2.0)),  # 45 deg to the left
        (PanoView(1.0, 1.0, 1.0, 0.0), (1.0 - 2.0, 1.0 - 3.0)),  # behind, to the right
        (PanoView(0.0, 0.0, 1.0, math.pi / 2), (-2.0, 2.0)),  # the camera turned: 45 deg left in its frame
    ],
)
def test_a_cylinder_covers_the_columns_and_rows_the_camera_model_projects(
    view: PanoView, xy: tuple[float, float]
) -> None:
    radius_m, top_m = 0.3, 1.6
    _, labels = _paint(view, [Cylinder(xy[0], xy[1], radius_m, radius_m, 0.0, 0.0, top_m, RED, 7)])
    rows, cols = np.nonzero(labels == 7)
    dist_m = math.hypot(xy[0] - view.x_m, xy[1] - view.y_m)
    bearing = math.atan2(xy[1] - view.y_m, xy[0] - view.x_m) - view.yaw_rad
    centre = CAM.col_from_bearing(bearing)
    half_px = math.asin(radius_m / dist_m) * CAM.f_h_px  # the tangent rays (what Eq. 3 inverts)
    assert np.ptp(cols) + 1 == pytest.approx(2 * half_px, abs=1.5)
    assert cols.mean() == pytest.approx(centre, abs=0.6)
    near_m = dist_m - radius_m  # the top and bottom edges nearest the camera
    _, v_top = CAM.project([near_m, 0.0, top_m])
    assert rows.min() == pytest.approx(float(v_top), abs=1.5)
    _, v_bottom = CAM.project([near_m, 0.0, 0.0])
    assert rows.max() == pytest.approx(float(v_bottom), abs=1.5)


def test_the_nearer_body_hides_the_farther_whatever_the_list_order() -> None:
    near = Cylinder(0.0, 2.0, 0.3, 0.3, 0.0, 0.0, 1.2, BLUE, 1)
    far = Cylinder(0.0, 5.0, 0.3, 0.3, 0.0, 0.0, 1.8, RED, 2)
    view = PanoView(0.0, 0.0, 1.0, 0.0)
    for prims in ([near, far], [far, near]):
        pano, labels = _paint(view, prims)
        row = int(CAM.v0_px)
        col = round(CAM.col_from_bearing(math.pi / 2))
        assert labels[row, col] == 1 and pano[row, col, 0] > 200 and pano[row, col, 2] == 0
        _, v_far_top = CAM.project([0.0, 4.7, 1.8])
        _, v_near_top = CAM.project([0.0, 1.7, 1.2])
        assert v_far_top + 4 < v_near_top  # the far one shows above the near one's top
        assert labels[int(v_far_top) + 2, col] == 2


def test_a_head_is_painted_around_its_centre_height_with_its_colours() -> None:
    head = Head(0.0, 3.0, 1.6, 0.09, 0.12, -math.pi / 2, (150, 170, 200), (10, 10, 10), 6)  # facing the camera
    pano, labels = _paint(PanoView(0.0, 0.0, 1.0, 0.0), [head])
    rows, cols = np.nonzero(labels == 6)
    u_c, v_c = CAM.project([0.0, 3.0, 1.6])
    assert cols.mean() == pytest.approx(float(u_c), abs=0.6)
    assert rows.mean() == pytest.approx(float(v_c), abs=1.0)
    face = pano[round(float(v_c)), round(float(u_c))]
    assert face[2] > 100 > pano[rows.min(), round(float(u_c))][2]  # skin in the middle, hair on top


def test_a_body_straight_ahead_wraps_round_the_seam_and_labels_are_optional() -> None:
    pano = np.zeros((CAM.height_px, CAM.width_px, 3), np.uint8)
    paint_primitives(pano, CAM, PanoView(0.0, 0.0, 1.0, 0.0), [Cylinder(3.0, 0.0, 0.3, 0.3, 0.0, 0.0, 1.0, RED, 1)])
    cols = np.flatnonzero(pano.any(axis=(0, 2)))
    half_px = math.asin(0.3 / 3.0) * CAM.f_h_px
    # Straight ahead is column 0: the body wraps round the seam, split between both edges.
    assert {0, CAM.width_px - 1} <= set(cols.tolist())
    assert len(cols) == pytest.approx(2 * half_px, abs=1.5)
