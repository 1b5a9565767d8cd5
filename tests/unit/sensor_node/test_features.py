"""Annotation (I, theta, w, h): angles from the camera model, histogram, wire form."""

from __future__ import annotations

import math

import numpy as np
import pytest

from common.cameras import PtzCamera, design_pal
from common.codec import decode, encode
from common.schema import Blob
from sensor_node.features import PanoramicGeometry, PinholeGeometry, annotate, colour_histogram, to_wire
from sensor_node.segmentation.blobs import RawBlob
from sensor_node.unwarp import PanoFrame
from tests.unit.sensor_node.sn_synth import backdrop, draw_person


def _raw(img: np.ndarray, u0: int, v0: int, w: int, h: int, mask: np.ndarray) -> RawBlob:
    return RawBlob(u0, v0, w, h, mask, int(mask.sum()), float(mask.mean()))


def test_panoramic_annotation_matches_camera_model() -> None:
    _, cam = design_pal()
    img = backdrop(0)
    mask = np.zeros((100, 20), bool)
    mask[0:12, 6:14] = True  # head centred on column 9.5 of the box
    mask[12:, :] = True
    f = annotate(_raw(img, 500, 40, 20, 100, mask), PanoFrame.from_image(img), PanoramicGeometry(cam))
    assert f.bearing_rad == pytest.approx(cam.bearing_from_col(509.5), abs=1e-9)
    assert f.width_rad == pytest.approx(20 / cam.f_h_px)
    assert f.top_elev_rad == pytest.approx(cam.elevation_from_row(39.5))
    assert f.bottom_elev_rad == pytest.approx(cam.elevation_from_row(139.5))
    assert f.feet_visible
    assert sum(f.hist) == pytest.approx(1.0) and len(f.hist) == 64
    b = decode(encode(to_wire(f, 7)), Blob)
    assert b.local_id == 7 and b.bbox_u_px == 500 and b.bearing_rad == pytest.approx(f.bearing_rad)
    assert b.confidence == 1.0
    # A blob reaching the top row: the head may be above the view, its bearing is less sure.
    cut = annotate(_raw(img, 500, 0, 20, 100, mask), PanoFrame.from_image(img), PanoramicGeometry(cam))
    assert cut.confidence < 0.5 and to_wire(cut, 1).confidence == cut.confidence


def test_bearing_wraps_across_the_seam() -> None:
    _, cam = design_pal()
    img = backdrop(0)
    mask = np.ones((60, 20), bool)  # box 1075..1094 -> centre 1084.5 -> column 4.5
    f = annotate(_raw(img, 1075, 102, 20, 60, mask), PanoFrame.from_image(img), PanoramicGeometry(cam))
    assert f.bearing_rad == pytest.approx(cam.bearing_from_col(4.5), abs=1e-9)
    assert not f.feet_visible  # touches the bottom row
    assert -math.pi <= to_wire(f, 0).bearing_rad <= math.pi


def test_pinhole_annotation_gives_world_azimuths() -> None:
    ptz = PtzCamera(1.0, 2.0, 2.0, 640, 480, math.radians(60), pan_rad=math.radians(30), tilt_rad=0.0)
    geo = PinholeGeometry(ptz.pinhole())
    mask = np.ones((100, 41), bool)
    f = annotate(_raw(np.zeros((480, 640, 3), np.uint8), 299, 200, 41, 100, mask), None, geo)
    assert f.bearing_rad == pytest.approx(math.radians(30), abs=1e-3)  # image centre column 319.5
    assert f.width_rad == pytest.approx(2 * math.atan(20.5 / ptz.focal_px), rel=1e-3)
    assert f.top_elev_rad > 0 > f.bottom_elev_rad
    assert f.hist == []


def test_histogram_tells_shirts_apart() -> None:
    red, blue = backdrop(1), backdrop(1)
    draw_person(red, 100.0, shirt=(30, 30, 200))
    draw_person(blue, 100.0, shirt=(200, 60, 30))
    mask = np.ones((60, 16), bool)
    h1 = np.array(colour_histogram(red[100:160, 92:108], mask, (16, 4)))
    h2 = np.array(colour_histogram(blue[100:160, 92:108], mask, (16, 4)))
    assert np.minimum(h1, h2).sum() < 0.2  # histogram intersection
