"""What people and camera platforms are made of, for the simulated cameras.

Everything is built from two primitives whose silhouettes can be computed
exactly: vertical elliptic cylinders (legs, torso, arms, neck, robot bodies,
masts, camera heads) and ellipsoid heads. Colours are BGR (OpenCV order);
the world gives RGB.

A person of height H (top of the head) has: an ellipsoid head 0.23 H/1.75 m
tall and ~2/3 as wide, centred on the person's position (the head bearing the
sensor nodes measure); a neck; an elliptic torso (shoulder width across the
walking direction, shallower along it); two arms and two legs that swing with
the gait phase; shoes. A camera platform is a white cylinder of radius R with
a dark base and a coloured band, a thin mast up to the camera, and the camera
head on the axis at the camera height (the optical centre).

Labels (for the test/debug label image only): person head ``2 * id``, rest of
the person ``2 * id + 1``, platform k of the world's camera list ``1000 + k``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from common.arrays import BoolArray, Float32Array, FloatArray
from sim.world import PersonState, PlatformState

__all__ = [
    "PLATFORM_LABEL0",
    "WHITE_BGR",
    "Cylinder",
    "Head",
    "Primitive",
    "band_z_range",
    "head_label",
    "person_primitives",
    "platform_primitives",
]

BGR = tuple[int, int, int]
WHITE_BGR: BGR = (236, 238, 238)
PLATFORM_LABEL0 = 1000


@dataclass(frozen=True, slots=True)
class Cylinder:
    """A vertical elliptic cylinder between heights z0 and z1."""

    x_m: float
    y_m: float
    a_m: float
    """Semi-axis across ``heading_rad``."""
    b_m: float
    """Semi-axis along ``heading_rad``."""
    heading_rad: float
    z0_m: float
    z1_m: float
    bands: tuple[tuple[float, BGR], ...]
    """(z from which this colour applies, colour), ascending; the first applies from z0."""
    label: int
    shade_depth: float = 0.5
    """How much darker the side gets towards the silhouette (0: flat; matte white bodies ~0.15)."""


@dataclass(frozen=True, slots=True)
class Head:
    """An ellipsoid head: horizontal radius r_h, vertical semi-axis r_v, centre at z_c."""

    x_m: float
    y_m: float
    zc_m: float
    rh_m: float
    rv_m: float
    heading_rad: float
    """The face looks this way; the back and top of the head show hair."""
    skin_bgr: BGR
    hair_bgr: BGR
    label: int


Primitive = Cylinder | Head

HAIR_TOP = 0.4
"""Above this height on the head (its vertical semi-axis = 1) the head shows hair..."""
HAIR_BACK = -0.2
"""...and where it faces away more than this (cosine of the angle to the face's direction)..."""
HAIR_SIDE = 0.35
HAIR_SIDE_TOP = -0.05
"""...and on the sides (facing below HAIR_SIDE) above this height; the face is the rest."""


def band_colours(bands: tuple[tuple[float, tuple[int, int, int]], ...], z: FloatArray) -> Float32Array:
    """The BGR colour of a cylinder's bands (``Cylinder.bands``: from each height up) at heights ``z``."""
    out = np.empty((*z.shape, 3), np.float32)
    out[:] = np.asarray(bands[0][1], np.float32)
    for z_from, bgr in bands[1:]:
        out[z >= z_from] = np.asarray(bgr, np.float32)
    return out


def is_hair(height: FloatArray, facing: FloatArray) -> BoolArray:
    """Where a head shows hair rather than skin, from the height on it (-1 chin .. 1 crown) and how much
    that point faces the way the face looks (the cosine)."""
    return (height > HAIR_TOP) | (facing < HAIR_BACK) | ((facing < HAIR_SIDE) & (height > HAIR_SIDE_TOP))


def _bgr(rgb: tuple[int, int, int]) -> BGR:
    return (int(rgb[2]), int(rgb[1]), int(rgb[0]))


def head_label(person_id: int) -> int:
    """Label of a person's head in the debug label image."""
    return 2 * person_id


def head_size(height_m: float) -> tuple[float, float]:
    """(horizontal radius, vertical semi-axis) of the head of a person ``height_m`` tall."""
    k = height_m / 1.75
    return 0.082 * k, 0.115 * k


def person_primitives(p: PersonState) -> list[Primitive]:
    """The parts of one person, in a painting order for equal depths (legs, torso, arms, neck, head)."""
    h = p.height_m
    rh, rv = head_size(h)
    zc = h - rv
    shoulder = h - 2.0 * rv - 0.05
    hip = 0.53 * h
    cos_h, sin_h = math.cos(p.heading_rad), math.sin(p.heading_rad)
    swing = min(1.0, p.speed_mps / 1.0) * math.sin(p.gait_phase_rad)
    shirt, pants, skin = _bgr(p.shirt_rgb), _bgr(p.pants_rgb), _bgr(p.skin_rgb)
    body = 2 * p.person_id + 1
    half_w = 0.5 * p.body_width_m
    parts: list[Primitive] = []

    def at(lateral_m: float, forward_m: float) -> tuple[float, float]:
        # lateral: to the person's left; forward: along the heading.
        return (p.x_m + forward_m * cos_h - lateral_m * sin_h, p.y_m + forward_m * sin_h + lateral_m * cos_h)

    for side in (1.0, -1.0):
        x, y = at(side * 0.075, side * 0.07 * swing)
        parts.append(
            Cylinder(x, y, 0.065, 0.07, p.heading_rad, 0.0, hip - 0.03, ((0.0, _bgr(p.shoe_rgb)), (0.07, pants)), body)
        )
    parts.append(
        Cylinder(
            p.x_m,
            p.y_m,
            half_w - 0.06,
            0.12,
            p.heading_rad,
            hip - 0.05,
            shoulder,
            ((0.0, pants), (hip + 0.02, shirt)),
            body,
        )
    )
    for side in (1.0, -1.0):
        x, y = at(side * (half_w - 0.02), -side * 0.11 * swing)
        parts.append(
            Cylinder(
                x, y, 0.045, 0.05, p.heading_rad, hip - 0.1, shoulder - 0.01, ((0.0, skin), (hip - 0.01, shirt)), body
            )
        )
    parts.append(
        Cylinder(p.x_m, p.y_m, 0.05, 0.055, p.heading_rad, shoulder - 0.02, zc - 0.6 * rv, ((0.0, skin),), body)
    )
    parts.append(Head(p.x_m, p.y_m, zc, rh, rv, p.heading_rad, skin, _bgr(p.hair_rgb), head_label(p.person_id)))
    return parts


def band_z_range(body_height_m: float) -> tuple[float, float]:
    """Heights (z0, z1) of the coloured marking band on a body ``body_height_m`` tall."""
    return 0.55 * body_height_m, 0.72 * body_height_m


def platform_primitives(pl: PlatformState, index: int) -> list[Primitive]:
    """A camera platform: white cylinder body with its band, mast, camera head (or a PTZ housing)."""
    label = PLATFORM_LABEL0 + index
    dark, black = (58, 58, 62), (28, 28, 30)
    parts: list[Primitive] = []
    top = 0.0
    if pl.radius_m > 0.0:
        b0, b1 = band_z_range(pl.body_height_m)
        bands = ((0.0, (70, 70, 72)), (0.05, WHITE_BGR), (b0, _bgr(pl.band_rgb)), (b1, WHITE_BGR))
        # A matte white body in diffuse room light: its edges stay bright, so it stands out (Eq. 3 needs them).
        parts.append(Cylinder(pl.x_m, pl.y_m, pl.radius_m, pl.radius_m, 0.0, 0.0, pl.body_height_m, bands, label, 0.08))
        top = pl.body_height_m
    if pl.kind == "ptz" and pl.radius_m <= 0.0:
        parts.append(Cylinder(pl.x_m, pl.y_m, 0.07, 0.07, 0.0, pl.z_m - 0.09, pl.z_m + 0.1, ((0.0, dark),), label))
        return parts
    if pl.z_m - 0.06 > top:
        parts.append(Cylinder(pl.x_m, pl.y_m, 0.02, 0.02, 0.0, top, pl.z_m - 0.05, ((0.0, dark),), label))
    glass = (95, 75, 55)
    parts.append(
        Cylinder(
            pl.x_m,
            pl.y_m,
            0.045,
            0.045,
            0.0,
            pl.z_m - 0.06,
            pl.z_m + 0.07,
            ((0.0, black), (pl.z_m - 0.025, glass), (pl.z_m + 0.025, black)),
            label,
        )
    )
    return parts
