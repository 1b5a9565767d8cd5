"""The static room for the simulated cameras: deterministic textures and ray casting against them.

The room is a box: the floor (z = 0), the ceiling (z = wall height) and four
walls. Its look is drawn once from the site seed -- painted plaster with
low-frequency blotches, a baseboard, the door (in the wall y = 0, where people
come in), windows, posters, a whiteboard with black-and-white bars, cabinets,
tiled floor, ceiling light panels -- so background subtraction has real
texture to model, and so the walls are the same in every process.

Rays are given as a horizontal unit direction (dx, dy) and a slope dz (rise
per metre of horizontal travel); the ray parameter t is then the horizontal
distance, which is also the depth used for occlusion. A panoramic camera's
rays factor into a per-column direction and a per-row slope (cheap
broadcasting); a perspective camera's rays are per pixel.

Wall texture coordinates: ``s`` runs along the perimeter counter-clockwise
from the corner (0, 0): the wall y = 0 (s = x), then x = X, then y = Y, then
x = 0; rows are heights (row = z * px_per_m).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np

from common.arrays import Float32Array, FloatArray, U8Image
from sim.world import World

__all__ = ["PX_PER_M", "RoomTextures", "cast_room", "make_textures"]

WALLS = 4
"""The room's walls, unrolled side by side into one texture (the last one runs to its end)."""

PX_PER_M = 50.0
"""Texture resolution (texels per metre): 2 cm, finer than a panorama pixel at 2 m."""


@dataclass(frozen=True, slots=True)
class RoomTextures:
    """Texture images of the room (BGR uint8)."""

    floor: U8Image
    """Rows = y * px_per_m, columns = x * px_per_m."""
    ceiling: U8Image
    walls: U8Image
    """Rows = z * px_per_m, columns = s * px_per_m (perimeter coordinate)."""
    room_x_m: float
    room_y_m: float
    wall_height_m: float


def _blotches(rng: np.random.Generator, h: int, w: int, cell_px: int, amp: float) -> Float32Array:
    """Smooth random field (low-frequency noise) of amplitude ``amp``."""
    small = rng.normal(0.0, 1.0, (max(2, h // cell_px + 2), max(2, w // cell_px + 2))).astype(np.float32)
    return cv2.resize(small, (w, h), interpolation=cv2.INTER_CUBIC) * np.float32(amp)


def _picture(rng: np.random.Generator, h: int, w: int) -> U8Image:
    """A poster: a few coloured blocks and stripes on a light ground."""
    img = np.full((h, w, 3), rng.integers(170, 245, 3), dtype=np.uint8)
    for _ in range(int(rng.integers(3, 8))):
        x0, y0 = int(rng.integers(0, w)), int(rng.integers(0, h))
        x1, y1 = x0 + int(rng.integers(3, max(4, w // 2))), y0 + int(rng.integers(3, max(4, h // 2)))
        cv2.rectangle(img, (x0, y0), (x1, y1), tuple(int(c) for c in rng.integers(20, 235, 3)), -1)
    return img


def make_textures(world: World) -> RoomTextures:
    """Draw the room's textures from the world's seed (deterministic)."""
    rng = np.random.default_rng([world.seed, 0x5CE])
    ppm = PX_PER_M
    xs, ys, hz = world.room_x_m, world.room_y_m, world.wall_height_m
    fw, fh = round(xs * ppm) + 2, round(ys * ppm) + 2
    # Floor: 0.5 m tiles, each its own shade, grout lines, speckle; darker towards the walls.
    base = np.array([150, 160, 168], dtype=np.float32) * rng.uniform(0.8, 1.05)
    floor = np.empty((fh, fw, 3), np.float32)
    floor[:] = base
    tile = int(0.5 * ppm)
    shade = rng.normal(1.0, 0.05, (fh // tile + 1, fw // tile + 1)).astype(np.float32)
    floor *= np.kron(shade, np.ones((tile, tile), np.float32))[:fh, :fw, None]
    floor += _blotches(rng, fh, fw, 20, 6.0)[..., None] + rng.normal(0, 5.0, (fh, fw, 1)).astype(np.float32)
    floor[::tile, :] *= 0.7
    floor[:, ::tile] *= 0.7
    yy, xx = np.mgrid[0:fh, 0:fw].astype(np.float32) / np.float32(ppm)
    edge = np.minimum(np.minimum(xx, xs - xx), np.minimum(yy, ys - yy))
    floor *= (1.0 - 0.3 * np.exp(-np.maximum(edge, 0) / 0.25))[..., None]
    # Ceiling: off-white with light panels.
    ceiling = np.full((fh, fw, 3), 215, np.float32) + _blotches(rng, fh, fw, 30, 4.0)[..., None]
    for cx in np.arange(1.0, xs - 0.5, 2.0):
        for cy in np.arange(1.0, ys - 0.5, 2.0):
            cv2.rectangle(ceiling, (int((cx - 0.3) * ppm), int((cy - 0.3) * ppm)),
                          (int((cx + 0.3) * ppm), int((cy + 0.3) * ppm)), (252, 252, 250), -1)  # fmt: skip
    walls = _walls(world, rng)
    return RoomTextures(
        floor=np.clip(floor, 0, 255).astype(np.uint8),
        ceiling=np.clip(ceiling, 0, 255).astype(np.uint8),
        walls=walls,
        room_x_m=xs,
        room_y_m=ys,
        wall_height_m=hz,
    )


def _walls(world: World, rng: np.random.Generator) -> U8Image:
    ppm = PX_PER_M
    xs, ys, hz = world.room_x_m, world.room_y_m, world.wall_height_m
    lengths = [xs, ys, xs, ys]
    starts = np.cumsum([0.0, *lengths])
    ww, wh = round(starts[-1] * ppm) + 2, round(hz * ppm) + 2
    img = np.zeros((wh, ww, 3), np.float32)
    # Mid-tone paint (BGR), so the white robot bodies stand out against the walls as they do in the paper.
    paints = [(168, 178, 186), (150, 172, 182), (182, 176, 160), (160, 184, 166), (186, 170, 156)]
    order = rng.permutation(len(paints))
    light = [1.0, 0.9, 0.96, 0.86]  # each wall faces the lights differently
    for k in range(WALLS):
        c0, c1 = round(starts[k] * ppm), (round(starts[k + 1] * ppm) + 1 if k < WALLS - 1 else ww)
        img[:, c0:c1] = np.array(paints[order[k]], np.float32) * light[k]
    img += _blotches(rng, wh, ww, 25, 7.0)[..., None] + rng.normal(0, 3.0, (wh, ww, 1)).astype(np.float32)

    def col(k: int, along_m: float) -> int:
        return round((starts[k] + along_m) * ppm)

    def row(z_m: float) -> int:
        return round(z_m * ppm)

    # Items on each wall: (wall, start along wall, width, z0, z1); avoid overlaps crudely by slots.
    door = world.door
    for k in range(WALLS):
        length = lengths[k]
        slots = np.arange(0.3, length - 1.2, 1.6)
        rng.shuffle(slots)
        for s0 in slots[: max(1, len(slots) * 2 // 3)]:
            if k == 0 and s0 + 1.4 > door.x0_m - 0.2 and s0 < door.x1_m + 0.2:
                continue
            kind = rng.choice(["poster", "poster", "window", "cabinet", "board"])
            w = float(rng.uniform(0.5, 1.3))
            _paint_item(img, kind, s0=s0, w=w, hz=hz, rng=rng, col=functools.partial(col, k), row=row)
    # Door (wall y = 0): wood with a frame and a handle.
    d0, d1, dz = col(0, door.x0_m), col(0, door.x1_m), row(door.height_m)
    cv2.rectangle(img, (d0 - 3, 0), (d1 + 3, dz + 3), (200, 200, 200), -1)
    wood = np.array([60, 95, 140], np.float32) + _blotches(rng, dz, d1 - d0, 6, 10.0)[..., None]
    img[0:dz, d0:d1] = wood
    cv2.circle(img, (d1 - 5, row(1.0)), 2, (40, 170, 200), -1)
    # Baseboard and a darker band near the ceiling corner.
    img[0 : row(0.09)] = np.array([70, 70, 75], np.float32) * 0.9
    img[0 : row(0.09), d0:d1] = wood[0 : row(0.09)]
    img[row(hz) - 3 :] *= 0.85
    return np.clip(img, 0, 255).astype(np.uint8)


def cast_room(
    tex: RoomTextures,
    origin_xyz: tuple[float, float, float],
    dir_x: FloatArray,
    dir_y: FloatArray,
    slope: FloatArray,
) -> tuple[U8Image, Float32Array]:
    """Colour and depth of the room surface each ray hits.

    Args:
        tex: the room textures.
        origin_xyz: ray origin (the camera centre), inside the room.
        dir_x: x of the unit horizontal direction (broadcast against ``slope``).
        dir_y: y of the unit horizontal direction.
        slope: rise per metre of horizontal travel (tan of the elevation).

    Returns:
        (BGR image, horizontal hit distance in metres), both of the broadcast shape.
    """
    ox, oy, oz = origin_xyz
    xs, ys, hz = tex.room_x_m, tex.room_y_m, tex.wall_height_m
    eps = 1e-9
    with np.errstate(divide="ignore", invalid="ignore"):
        tx = np.where(dir_x > eps, (xs - ox) / dir_x, np.where(dir_x < -eps, -ox / dir_x, np.inf))
        ty = np.where(dir_y > eps, (ys - oy) / dir_y, np.where(dir_y < -eps, -oy / dir_y, np.inf))
        t_floor = np.where(slope < -eps, oz / -slope, np.inf)
        t_ceil = np.where(slope > eps, (hz - oz) / slope, np.inf)
    t_wall = np.minimum(tx, ty)
    wx, wy = ox + t_wall * dir_x, oy + t_wall * dir_y
    # Perimeter coordinate of the wall hit point (see module docstring).
    s = np.where(
        tx < ty,
        np.where(dir_x > 0, xs + wy, 2 * xs + ys + (ys - wy)),
        np.where(dir_y < 0, wx, xs + ys + (xs - wx)),
    )
    shape = np.broadcast_shapes(np.shape(dir_x), np.shape(slope))
    t_wall_b = np.broadcast_to(t_wall, shape)
    z_wall = np.broadcast_to(oz + t_wall * slope, shape)
    ppm = np.float32(PX_PER_M)
    wall_map_x = np.broadcast_to(s * PX_PER_M, shape).astype(np.float32)
    wall_map_y = np.clip(z_wall * PX_PER_M, 0, tex.walls.shape[0] - 1).astype(np.float32)
    img = cv2.remap(tex.walls, wall_map_x, wall_map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    depth = t_wall_b.astype(np.float32)
    for t_hit, texture in ((t_floor, tex.floor), (t_ceil, tex.ceiling)):
        hit = np.broadcast_to(t_hit < t_wall, shape)
        if not hit.any():
            continue
        t_b = np.broadcast_to(np.where(np.isfinite(t_hit), t_hit, 0.0), shape)
        mx = np.clip((ox + t_b * dir_x) * ppm, 0, texture.shape[1] - 1).astype(np.float32)
        my = np.clip((oy + t_b * dir_y) * ppm, 0, texture.shape[0] - 1).astype(np.float32)
        part = cv2.remap(texture, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        img[hit] = part[hit]
        depth[hit] = t_b[hit]
    return np.asarray(img, dtype=np.uint8), depth


def _paint_item(
    img: Float32Array,
    kind: str,
    *,
    s0: float,
    w: float,
    hz: float,
    rng: np.random.Generator,
    col: Callable[[float], int],
    row: Callable[[float], int],
) -> None:
    """Paint one wall item (poster, window, cabinet or whiteboard) ``w`` m wide from ``s0`` m along its wall.

    ``col`` maps metres along the wall to texture columns, ``row`` heights to rows.
    """
    if kind == "poster":
        z0 = float(rng.uniform(1.1, 1.5))
        z1 = z0 + float(rng.uniform(0.4, 0.8))
        ph, pw = max(2, row(z1) - row(z0)), max(2, col(s0 + w) - col(s0))
        img[row(z0) : row(z0) + ph, col(s0) : col(s0) + pw] = _picture(rng, ph, pw)
    elif kind == "window":
        z0, z1 = 0.9, min(2.3, hz - 0.3)
        cv2.rectangle(img, (col(s0), row(z0)), (col(s0 + w), row(z1)), (120, 110, 100), -1)
        sh, sw = row(z1) - row(z0) - 4, col(s0 + w) - col(s0) - 4
        sky = np.array([235, 225, 200], np.float32) + _blotches(rng, sh, sw, 8, 12.0)[..., None]
        img[row(z0) + 2 : row(z1) - 2, col(s0) + 2 : col(s0 + w) - 2] = sky
        cv2.line(img, (col(s0 + w / 2), row(z0)), (col(s0 + w / 2), row(z1)), (120, 110, 100), 2)
    elif kind == "cabinet":
        z1 = float(rng.uniform(0.7, 1.0))
        colour = tuple(float(c) for c in rng.integers(60, 200, 3))
        cv2.rectangle(img, (col(s0), 0), (col(s0 + w), row(z1)), colour, -1)
        for j in range(1, 3):
            x = col(s0 + w * j / 3)
            cv2.line(img, (x, 0), (x, row(z1)), tuple(0.6 * c for c in colour), 1)
    else:  # whiteboard with equal black/white bars (the paper's Fig. 1 board)
        z0, z1 = 0.9, 1.9
        cv2.rectangle(img, (col(s0), row(z0)), (col(s0 + w), row(z1)), (160, 160, 165), -1)
        img[row(z0) + 2 : row(z1) - 2, col(s0) + 2 : col(s0 + w) - 2] = 245
        n = 8
        for j in range(0, n, 2):
            za, zb = z0 + 0.1 + 0.8 * j / n, z0 + 0.1 + 0.8 * (j + 1) / n
            cv2.rectangle(img, (col(s0 + 0.1), row(za)), (col(s0 + 0.35), row(zb)), (25, 25, 25), -1)
