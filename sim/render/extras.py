"""What real cameras see besides people: soft cast shadows on the floor and a distractor swaying in place.

Used by :class:`sim.render.cameras.PanoramicRenderer` when ``[world.lighting]`` asks for them
(``shadow_gain`` < 1, ``sway_m`` > 0), so the simulated sites exercise what PETS 2009 showed (issue 14):

* **shadows** -- each present person darkens the floor around and a little beside their feet to
  ``shadow_gain`` of its brightness (hue kept: light is taken away, not paint added), fading out at the
  edge; painted on the room before the people, so people occlude them;
* **a swaying plant** -- a dark green column, ``PLANT_HEIGHT_M`` tall, near the room corner (0, Y) that
  leans back and forth by ``sway_m`` at ``SWAY_HZ`` with a second, faster flutter of its leaves: it moves
  in place for ever, the case a background model must absorb.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from common.cameras import CylindricalCamera

__all__ = ["FloorMap", "paint_plant", "paint_shadows"]

SHADOW_RADIUS_M = (0.45, 0.3)
"""Semi-axes of a cast shadow on the floor (along the light's direction, across it)."""

SHADOW_OFFSET_M = 0.25
"""The shadow's centre lies this far from the feet, away from the light (ceiling lights towards +x)."""

PLANT_HEIGHT_M = 1.6
PLANT_RADIUS_M = 0.18
PLANT_INSET_M = 0.4
"""The plant stands this far from both walls of the corner (0, Y)."""

SWAY_HZ = 0.7
"""Sway frequency (a draught); the leaves flutter at 3.1 times it."""
PLANT_NEAR_M = 0.5
"""A camera closer than this to the plant does not draw it (it would fill the view)."""


class FloorMap:
    """The floor point each panorama pixel sees (NaN where it sees a wall or the ceiling)."""

    def __init__(self, x_m: npt.NDArray[np.float64], y_m: npt.NDArray[np.float64]) -> None:
        self.x_m = x_m
        self.y_m = y_m

    @classmethod
    def for_view(
        cls,
        origin: tuple[float, float, float],
        theta: npt.NDArray[np.float64],
        slope: npt.NDArray[np.float64],
        depth: npt.NDArray[np.float32],
    ) -> FloorMap:
        """From the render camera's per-column bearings, per-row slopes and the room's hit depth."""
        ox, oy, oz = origin
        with np.errstate(divide="ignore"):
            t_floor = np.where(slope < 0, oz / -np.minimum(slope, -1e-9), np.inf)
        t = np.broadcast_to(t_floor, depth.shape)
        on_floor = np.abs(t - depth) < 1e-3 * np.maximum(t, 1.0)
        x = np.where(on_floor, ox + t * np.cos(theta), np.nan)
        y = np.where(on_floor, oy + t * np.sin(theta), np.nan)
        return cls(x, y)


def paint_shadows(pano: npt.NDArray[np.uint8], floor: FloorMap, feet: list[tuple[float, float]], gain: float) -> None:
    """Darken the floor around each (x, y) of ``feet`` to ``gain`` (soft edge), in place."""
    if gain >= 1.0 or not feet:
        return
    a, b = SHADOW_RADIUS_M
    factor = np.ones(pano.shape[:2], np.float32)
    for x, y in feet:
        cx = x + SHADOW_OFFSET_M
        with np.errstate(invalid="ignore"):
            r2 = ((floor.x_m - cx) / a) ** 2 + ((floor.y_m - y) / b) ** 2
            inside = r2 < 1.0
        if not inside.any():
            continue
        soft = np.clip((1.0 - r2[inside]) * 3.0, 0.0, 1.0).astype(np.float32)  # fades over the outer third
        factor[inside] = np.minimum(factor[inside], 1.0 - (1.0 - gain) * soft)
    rows = np.flatnonzero((factor < 1.0).any(axis=1))
    if rows.size:
        sl = slice(int(rows[0]), int(rows[-1]) + 1)
        pano[sl] = np.clip(pano[sl].astype(np.float32) * factor[sl, :, None], 0, 255).astype(np.uint8)


def paint_plant(
    pano: npt.NDArray[np.uint8],
    cam: CylindricalCamera,
    view: tuple[float, float, float, float],
    room_y_m: float,
    *,
    sway_m: float,
    t_s: float,
) -> None:
    """A plant near the corner (0, Y) leaning by ``sway_m`` sin(2 pi SWAY_HZ t), painted into ``pano``."""
    if sway_m <= 0.0:
        return
    vx, vy, vz, yaw = view
    px, py = PLANT_INSET_M, room_y_m - PLANT_INSET_M
    d = math.hypot(px - vx, py - vy)
    if d < PLANT_NEAR_M:
        return
    lean = sway_m * math.sin(2 * math.pi * SWAY_HZ * t_s)
    flutter = 0.3 * sway_m * math.sin(2 * math.pi * 3.1 * SWAY_HZ * t_s + 1.0)
    h, w = pano.shape[:2]
    rows = np.arange(h, dtype=np.float64)
    elev = np.asarray(cam.elevation_from_row(rows), np.float64)
    z = vz + d * np.tan(elev)
    on = (z >= 0.0) & (z <= PLANT_HEIGHT_M)
    if not on.any():
        return
    frac = np.clip(z / PLANT_HEIGHT_M, 0.0, 1.0)
    # The stem is fixed at the pot; the crown leans most, its leaves fluttering on top of the lean.
    shift_m = lean * frac**2 + flutter * frac**3
    # Sideways shift as seen from the camera: across the line of sight.
    ux, uy = -(py - vy) / d, (px - vx) / d
    xs, ys = px + shift_m * ux, py + shift_m * uy
    bearing = np.arctan2(ys - vy, xs - vx) - yaw
    col = np.asarray(cam.col_from_bearing(bearing), np.float64)
    half = (PLANT_RADIUS_M * (0.4 + 0.6 * frac)) / d * cam.f_h_px
    for r in np.flatnonzero(on):
        c0, c1 = math.floor(col[r] - half[r] + 0.5), math.floor(col[r] + half[r] + 0.5)
        cols = np.arange(c0, max(c1, c0 + 1)) % w
        shade = 60 + 50 * frac[r]
        pano[r, cols] = (30, int(shade) + 40, 35)
