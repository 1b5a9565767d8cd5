"""What the simulated people look like, and the door they use.

Each person's clothing, skin, hair, height, shoulder width and preferred
walking speed are drawn from ``(seed, person)`` alone, so they never depend on
the simulation. Shirts come from a shuffled palette of distinct colours (no
whites: white is the robots' colour), so people differ in clothing as the
paper's colour histograms need. Colours are RGB.
"""

from __future__ import annotations

import random
from dataclasses import dataclass

from common.site import WorldSpec

__all__ = ["Door", "WalkerLook", "make_look"]

_SHIRTS = [
    (200, 40, 40), (40, 90, 200), (40, 150, 60), (230, 180, 30), (150, 60, 170), (240, 120, 30),
    (30, 160, 170), (120, 70, 40), (220, 100, 150), (20, 40, 100), (170, 200, 60), (130, 20, 40),
    (60, 60, 60), (90, 130, 230), (200, 60, 110), (110, 150, 100),
]  # fmt: skip
_PANTS = [(40, 50, 90), (30, 30, 35), (150, 130, 90), (85, 85, 90), (70, 50, 35), (60, 70, 50), (25, 35, 60)]
_SKIN = [(240, 200, 170), (225, 180, 140), (200, 150, 110), (160, 110, 75), (120, 80, 55), (95, 65, 45)]
_HAIR = [(20, 15, 10), (60, 40, 25), (110, 75, 40), (190, 160, 100), (150, 150, 150), (120, 50, 20)]
_SHOES = [(20, 20, 20), (60, 40, 30), (230, 230, 225), (40, 40, 60)]

RGB = tuple[int, int, int]


@dataclass(frozen=True, slots=True)
class Door:
    """The room's door: a gap in the wall y = 0 between x0 and x1."""

    x0_m: float
    x1_m: float
    height_m: float = 2.1

    @property
    def inside_xy(self) -> tuple[float, float]:
        """Point just inside the room in front of the door."""
        return (0.5 * (self.x0_m + self.x1_m), 0.6)

    @property
    def outside_xy(self) -> tuple[float, float]:
        """Where people wait outside, behind the wall."""
        return (0.5 * (self.x0_m + self.x1_m), -0.9)


@dataclass(frozen=True, slots=True)
class WalkerLook:
    """What a person looks like and how fast they like to walk (fixed for the run)."""

    person_id: int
    height_m: float
    """Top of the head above the floor."""
    body_width_m: float
    """Shoulder width."""
    speed_mps: float
    """Preferred walking speed."""
    shirt_rgb: RGB
    pants_rgb: RGB
    skin_rgb: RGB
    hair_rgb: RGB
    shoe_rgb: RGB


def make_look(spec: WorldSpec, seed: int, i: int) -> WalkerLook:
    """Person i's looks and preferred speed, drawn from (seed, i) alone."""
    rng = random.Random(f"walker:{seed}:{i}:-1")
    palette = random.Random(f"palette:{seed}")
    shirts = list(_SHIRTS)
    palette.shuffle(shirts)
    pants = list(_PANTS)
    palette.shuffle(pants)
    shirt = shirts[i % len(shirts)]
    if i >= len(shirts):  # more people than shirts: vary the shade
        k = 0.6 + 0.3 * ((i // len(shirts)) % 2)
        shirt = (int(shirt[0] * k), int(shirt[1] * k), int(shirt[2] * k))
    lo_h, hi_h = spec.person_height_m
    lo_v, hi_v = spec.person_speed_mps
    height = rng.uniform(lo_h, hi_h)
    return WalkerLook(
        person_id=i + 1,
        height_m=height,
        body_width_m=0.40 + 0.12 * (height - 1.5) / 0.4 * rng.uniform(0.6, 1.0),
        speed_mps=rng.uniform(lo_v, hi_v),
        shirt_rgb=shirt,
        pants_rgb=pants[i % len(pants)],
        skin_rgb=rng.choice(_SKIN),
        hair_rgb=rng.choice(_HAIR),
        shoe_rgb=rng.choice(_SHOES),
    )
