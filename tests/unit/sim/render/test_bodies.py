"""Bodies from primitives: a person's head where the world puts them, a platform's body and camera at its heights."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.render.bodies import (
    PLATFORM_LABEL0,
    Cylinder,
    Head,
    band_colours,
    band_z_range,
    head_label,
    head_size,
    person_primitives,
    platform_primitives,
)
from sim.world import PersonState, PlatformState


def _person(height_m: float = 1.8, heading_rad: float = 0.0) -> PersonState:
    return PersonState(
        person_id=3, x_m=2.0, y_m=1.0, height_m=height_m, heading_rad=heading_rad, present=True, body_width_m=0.45,
        shirt_rgb=(200, 40, 40), pants_rgb=(40, 50, 90), skin_rgb=(240, 200, 170), hair_rgb=(20, 15, 10),
        shoe_rgb=(20, 20, 20), speed_mps=1.0, gait_phase_rad=0.3,
    )  # fmt: skip


def _platform(kind: str = "panoramic", radius_m: float = 0.2) -> PlatformState:
    return PlatformState(
        sensor_id="r1", kind=kind, x_m=1.0, y_m=1.5, yaw_rad=0.0, z_m=1.1, radius_m=radius_m,
        body_height_m=0.9, band_rgb=(10, 20, 30), mobile=True,
    )  # fmt: skip


@pytest.mark.parametrize("height_m", [1.5, 1.75, 1.95])
def test_a_persons_head_tops_out_at_their_height_centred_on_their_position(height_m: float) -> None:
    parts = person_primitives(_person(height_m))
    heads = [p for p in parts if isinstance(p, Head)]
    assert len(heads) == 1
    head = heads[0]
    assert (head.x_m, head.y_m) == (2.0, 1.0)
    assert head.zc_m + head.rv_m == pytest.approx(height_m)
    assert (head.rh_m, head.rv_m) == pytest.approx(head_size(height_m))
    assert head.label == head_label(3)
    assert head.skin_bgr == (170, 200, 240)  # RGB in the world, BGR in the image
    bodies = [p for p in parts if isinstance(p, Cylinder)]
    assert min(c.z0_m for c in bodies) == 0.0  # feet on the floor
    assert max(c.z1_m for c in bodies) < head.zc_m  # nothing pokes through the head
    assert {c.label for c in bodies} == {head.label + 1}


def test_a_persons_shoulders_lie_across_the_walking_direction() -> None:
    for heading in (0.0, math.pi / 2):
        arms = [p for p in person_primitives(_person(heading_rad=heading)) if isinstance(p, Cylinder)][3:5]
        dx, dy = arms[0].x_m - arms[1].x_m, arms[0].y_m - arms[1].y_m
        along = abs(dx * math.cos(heading) + dy * math.sin(heading))
        across = abs(-dx * math.sin(heading) + dy * math.cos(heading))
        assert across > 0.3 > along


def test_a_platform_has_its_body_band_and_camera_at_the_optical_centre() -> None:
    parts = platform_primitives(_platform(), index=2)
    assert all(p.label == PLATFORM_LABEL0 + 2 for p in parts)
    body = parts[0]
    assert isinstance(body, Cylinder)
    assert (body.a_m, body.z1_m) == (0.2, 0.9)
    b0, b1 = band_z_range(0.9)
    assert 0.0 < b0 < b1 < 0.9
    z = np.array([b0 - 0.01, (b0 + b1) / 2, b1 + 0.01])
    colours = band_colours(body.bands, z)
    assert colours[1].tolist() == [30, 20, 10]  # the band's colour (BGR) between b0 and b1 only
    assert colours[0].tolist() == colours[2].tolist() != colours[1].tolist()
    camera = parts[-1]
    assert isinstance(camera, Cylinder) and camera.z0_m < 1.1 < camera.z1_m


def test_a_ptz_on_the_wall_is_only_its_housing() -> None:
    parts = platform_primitives(_platform(kind="ptz", radius_m=0.0), index=0)
    assert len(parts) == 1
    assert isinstance(parts[0], Cylinder) and parts[0].z0_m < 1.1 < parts[0].z1_m
