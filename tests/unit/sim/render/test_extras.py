"""Shadows darken the floor round people's feet (hue kept), and the plant sways in place where it stands."""

from __future__ import annotations

import math

import numpy as np
import pytest

from common.cameras import CylindricalCamera
from sim.render.extras import PLANT_INSET_M, SHADOW_OFFSET_M, FloorMap, paint_plant, paint_shadows

GREY_BLUE = (120, 100, 80)


def _floor() -> tuple[np.ndarray, FloorMap]:
    """A 60 x 60 image whose pixel (r, c) sees the floor at (c / 10, r / 10), except the top 10 rows (a wall)."""
    rows, cols = np.mgrid[0:60, 0:60].astype(np.float64)
    x, y = cols / 10.0, rows / 10.0
    x[:10], y[:10] = np.nan, np.nan
    return np.full((60, 60, 3), GREY_BLUE, np.uint8), FloorMap(x, y)


@pytest.mark.parametrize("gain", [0.5, 0.8])
def test_a_shadow_darkens_the_floor_beside_the_feet_keeping_its_hue(gain: float) -> None:
    pano, floor = _floor()
    paint_shadows(pano, floor, [(3.0, 3.0)], gain)
    centre = pano[30, round((3.0 + SHADOW_OFFSET_M) * 10)].astype(float)
    assert centre == pytest.approx(np.array(GREY_BLUE) * gain, abs=1.0)
    ratio = centre / np.array(GREY_BLUE)
    assert np.ptp(ratio) < 0.02  # the same factor on each channel: light taken away, no paint added
    assert pano[30, 5].tolist() == list(GREY_BLUE)  # far from the feet: untouched
    assert (pano[:10] == GREY_BLUE).all()  # the wall never takes a floor shadow


def test_no_shadow_at_full_gain_or_without_people() -> None:
    for feet, gain in (([(3.0, 3.0)], 1.0), ([], 0.5)):
        pano, floor = _floor()
        paint_shadows(pano, floor, feet, gain)
        assert (pano == GREY_BLUE).all()


def test_floor_map_keeps_only_pixels_whose_ray_ends_on_the_floor() -> None:
    theta = np.array([[0.5, 2.0]])
    slope = np.array([[-0.5], [0.2]])
    depth = np.array([[2.0, 1.5], [4.0, 4.0]], np.float32)  # row 0, column 1: a wall nearer than the floor
    floor = FloorMap.for_view((1.0, 1.0, 1.0), theta, slope, depth)
    assert (floor.x_m[0, 0], floor.y_m[0, 0]) == pytest.approx((1.0 + 2.0 * math.cos(0.5), 1.0 + 2.0 * math.sin(0.5)))
    assert np.isnan(floor.x_m[0, 1]) and np.isnan(floor.x_m[1]).all()


def _plant_columns(t_s: float, sway_m: float) -> np.ndarray:
    cam = CylindricalCamera(width_px=720, height_px=120, f_v_px=100.0, v0_px=60.0, height_m=1.0)
    pano = np.zeros((120, 720, 3), np.uint8)
    paint_plant(pano, cam, (3.0, 1.0, 1.0, 0.0), 5.0, sway_m=sway_m, t_s=t_s)
    return np.flatnonzero(pano.any(axis=(0, 2)))


def test_the_plant_stands_at_the_corner_and_sways_in_place() -> None:
    bearing = math.atan2(5.0 - PLANT_INSET_M - 1.0, PLANT_INSET_M - 3.0)
    col = bearing % (2 * math.pi) * 720 / (2 * math.pi)
    spans = [_plant_columns(t, 0.2) for t in np.arange(0.0, 1.5, 0.1)]
    assert all(abs(float(np.median(s)) - col) < 8 for s in spans)
    assert len({(int(s.min()), int(s.max())) for s in spans}) > 3  # it moves
    assert _plant_columns(0.3, 0.0).size == 0  # no sway configured: no plant
