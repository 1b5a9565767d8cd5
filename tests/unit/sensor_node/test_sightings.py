"""Sightings: band colour -> robot id, validation against shirts, sub-pixel boundaries, Eq. (3); body blobs."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from common.cameras import design_pal
from common.schema import Sighting
from sensor_node.config import BodySpec, PipelineSettings
from sensor_node.sightings import BandFinder, BodySighting, LeftPlaces, _hue_ranges, _runs, drove_off, is_body_blob
from sensor_node.unwarp import PanoFrame
from tests.unit.sensor_node.sn_synth import backdrop as _backdrop

_, CAM = design_pal()


def backdrop(seed: int) -> np.ndarray:
    """A pale, low-saturation wall (like a room's), brighter than the synthetic default."""
    img = _backdrop(seed).astype(np.float32)
    grey = img.mean(axis=2, keepdims=True)
    return np.clip(0.3 * img + 0.7 * grey + 40, 0, 255).astype(np.uint8)


BODIES = [BodySpec(id="red", band_rgb=[220, 40, 40]), BodySpec(id="blue", band_rgb=[40, 80, 220])]


def _draw_body(
    img: np.ndarray, left: float, right: float, band_bgr: tuple[int, int, int], rows: tuple[int, int]
) -> None:
    """A white cylinder from ``left`` to ``right`` (sub-pixel, anti-aliased by coverage) with a band."""
    width = img.shape[1]
    for c in range(math.floor(left), math.ceil(right) + 1):
        cover = max(0.0, min(c + 0.5, right) - max(c - 0.5, left))
        if cover <= 0:
            continue
        col = c % width
        for r in range(rows[0] - 25, img.shape[0]):
            colour = np.array(band_bgr if rows[0] <= r <= rows[1] else (236, 238, 238), np.float32)
            img[r, col] = (cover * colour + (1 - cover) * img[r, col].astype(np.float32) + 0.5).astype(np.uint8)


@pytest.mark.parametrize(("left", "right"), [(500.3, 521.1), (1070.6, 1091.2)])  # the second crosses the seam
def test_finds_and_measures_a_body(left: float, right: float) -> None:
    img = backdrop(2)
    _draw_body(img, left, right, (220, 80, 40), (130, 142))  # blue band (BGR)
    found = BandFinder(BODIES, CAM, PipelineSettings()).find(PanoFrame.from_image(img))
    assert [b.sighting.target_id for b in found] == ["blue"]
    b = found[0]
    assert b.left_col == pytest.approx(left, abs=0.25) and b.right_col == pytest.approx(right, abs=0.25)
    alpha = (right - left) / CAM.f_h_px
    assert b.sighting.alpha_rad == pytest.approx(alpha, rel=0.02)
    assert b.sighting.distance_m == pytest.approx(0.18 / math.sin(alpha / 2), rel=0.02)  # Eq. (3)
    mid = CAM.bearing_from_col(((left + right) / 2) % 1080)
    assert math.cos(b.sighting.bearing_rad - mid) == pytest.approx(1.0, abs=1e-5)


def test_a_shirt_of_the_band_colour_is_not_a_robot() -> None:
    img = backdrop(3)
    cv2.rectangle(img, (300, 95), (325, 161), (40, 40, 220), -1)  # a red shirt: no white body around it
    assert BandFinder(BODIES, CAM, PipelineSettings()).find(PanoFrame.from_image(img)) == []


@pytest.mark.parametrize(
    ("left", "right", "rows", "seen"),
    [
        (500.3, 521.1, (130, 142), True),  # Eq. 3: 2.95 m; the band's elevation: ~3.3 m
        (500.3, 510.4, (130, 142), False),  # too narrow for where its band is: Eq. 3 says 6 m
        (500.3, 521.1, (100, 106), False),  # a band near the horizon is far away, not 2.95 m
    ],
)
def test_the_band_elevation_must_agree_with_eq3(left: float, right: float, rows: tuple[int, int], seen: bool) -> None:
    img = backdrop(4)
    _draw_body(img, left, right, (220, 80, 40), rows)
    found = BandFinder(BODIES, CAM, PipelineSettings()).find(PanoFrame.from_image(img))
    assert [b.sighting.target_id for b in found] == (["blue"] if seen else [])


def test_a_band_cut_by_the_image_edge_is_measured_on_the_body_above_it() -> None:
    img = backdrop(5)
    left, right = 500.3, 532.4  # Eq. 3: 1.93 m, where a 1.1 m camera sees only the band's top rows
    _draw_body(img, left, right, (220, 80, 40), (159, 161))
    found = BandFinder(BODIES, CAM, PipelineSettings()).find(PanoFrame.from_image(img))
    assert [b.sighting.target_id for b in found] == ["blue"]
    assert found[0].left_col == pytest.approx(left, abs=0.3) and found[0].right_col == pytest.approx(right, abs=0.3)
    assert found[0].sighting.distance_m == pytest.approx(0.18 / math.sin((right - left) / CAM.f_h_px / 2), rel=0.02)


def test_hue_ranges_and_runs_wrap() -> None:
    assert _hue_ranges([220, 40, 40], 43.2) == [(0, 10), (170, 179)]  # red straddles hue 0
    ((lo, hi),) = _hue_ranges([40, 80, 220], 43.2)
    assert lo < 113 < hi
    cols = np.zeros(20, bool)
    cols[[0, 1, 5, 6, 7, 18, 19]] = True
    assert _runs(cols, wrap=True) == [(18, 4), (5, 3)]
    assert _runs(cols, wrap=False) == [(0, 2), (5, 3), (18, 2)]


def test_is_body_blob() -> None:
    img = backdrop(2)
    _draw_body(img, 500.3, 521.1, (220, 80, 40), (130, 142))
    (s,) = BandFinder(BODIES, CAM, PipelineSettings()).find(PanoFrame.from_image(img))
    assert is_body_blob(499, 24, 1080, [s])  # the moving robot itself (mast and head included)
    assert not is_body_blob(480, 70, 1080, [s])  # a person in front, much wider than the body
    assert not is_body_blob(600, 20, 1080, [s])
    # 2.95 m away, a 0.9 m robot with its camera at 1.1 m reaches ~0.15 m above the horizon row at most;
    # a blob of the same width whose top is a head well above that is a person passing the robot.
    horizon = CAM.v0_px
    assert s.top_row < horizon and is_body_blob(499, 24, 1080, [s], v0=round(s.top_row) + 2)
    assert not is_body_blob(499, 24, 1080, [s], v0=round(horizon) - 25)


def _at(left: float, right: float, target: str = "robot1") -> BodySighting:
    """A sighting of ``target`` between columns ``left`` and ``right`` (top row 70)."""
    s = Sighting(target_id=target, left_rad=0.0, right_rad=0.1, alpha_rad=0.1, bearing_rad=0.05, distance_m=2.0,
                 body_radius_m=0.18)  # fmt: skip
    return BodySighting(s, left, right, (80, 90), top_row=70.0)


@pytest.mark.parametrize(
    ("now", "off"),
    [
        ((500.2, 520.1), False),  # the same place, a fraction of a pixel of noise
        ((503.0, 523.0), False),  # 3 of 20 columns free: a nudge
        ((506.0, 526.0), True),  # a quarter free: it drives off sideways
        ((505.0, 515.0), True),  # narrower (driving away from the camera): both edges free
        ((-4.3, 15.7), False),  # the same place, numbered from the other side of the seam (columns wrap)
        ((1.5, 21.5), True),  # across the seam, a quarter free
    ],
)
def test_drove_off(now: tuple[float, float], off: bool) -> None:
    was = _at(500.0, 520.0) if now[0] > 100 else _at(1075.5, 1095.5)
    assert drove_off(was, _at(*now), 1080) is off


def test_a_robot_that_drove_off_leaves_its_place_for_still_absorb_frames() -> None:
    settings = PipelineSettings()
    left = LeftPlaces(1080, settings)
    assert left.update([_at(500.0, 520.0)], frame=1) == []  # stands where the model learnt it
    assert left.update([_at(500.1, 520.0)], frame=2) == []
    (place,) = left.update([_at(510.0, 530.0)], frame=3)  # drove off: its old place is a hole
    assert (place.left_col, place.right_col) == (500.0, 520.0)
    assert is_body_blob(502, 12, 1080, [place], v0=72)  # a blob there no taller than the robot: no person
    assert not is_body_blob(502, 12, 1080, [place], v0=40)  # someone taller standing there is one
    assert left.update([_at(530.0, 550.0)], frame=3 + settings.still_absorb_frames) != []
    assert left.update([_at(540.0, 560.0)], frame=4 + settings.still_absorb_frames) == []  # absorbed by then
    left.reset()  # a new model: it stands in it where it is now
    assert left.update([_at(540.0, 560.0)], frame=100) == []
