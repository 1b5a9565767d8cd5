"""Simulated cameras: render the world into the pixels a real camera would deliver.

:class:`PanoramicRenderer` produces the raw annular (PAL) image of a panoramic
camera (768 x 576 by default, the paper's Fig. 1b): it casts the cylindrical
panorama of the paper's -15 deg .. +20 deg vertical field of view column by
column -- the room (cached while the camera does not move), then the people and
the other cameras' bodies far to near -- and warps it into the ring through the
inverse of the lens's unwarp model (``AnnularModel.warp_maps`` of
``design_pal``), so the sensor node's real unwarp runs on real radial
distortion. The camera's own body is not in its own view.

:class:`PtzRenderer` produces the perspective image of a PTZ camera for its
current pan, tilt and zoom by per-pixel ray casting.

Optionally (``[world.lighting] shadow_gain``, ``sway_m``) soft cast shadows under the people and a plant
that sways in place (:mod:`sim.render.extras`).

Then the light: a slow sinusoidal illumination drift, sudden light changes at
the configured world times (alternately brighter by ``sudden_change_gain`` and
back), a fixed lens vignette and per-pixel Gaussian sensor noise, each set in
``[world.lighting]``. Only pixels leave a renderer; ground truth stays in the
world.
"""

from __future__ import annotations

import bisect
import logging
import math

import cv2
import numpy as np
import numpy.typing as npt

from common.arrays import U8Image
from common.cameras import AnnularModel, CylindricalCamera, PtzCamera, design_pal
from common.errors import ConfigError
from common.site import CameraSpec, LightingSpec
from sim.render.bodies import Primitive, person_primitives, platform_primitives
from sim.render.extras import FloorMap, paint_plant, paint_shadows
from sim.render.panoramic import PanoView, paint_primitives
from sim.render.ptz import RayGrid, paint_primitives_rays
from sim.render.room import RoomTextures, cast_room, make_textures
from sim.world import World

__all__ = ["PanoramicRenderer", "PtzRenderer", "light_gain"]

logger = logging.getLogger(__name__)


PANO_MARGIN_ROWS = 3
"""Rows rendered beyond each edge of the panorama (the ring's edges interpolate into them)."""

_TEXTURES: dict[tuple[float, ...], RoomTextures] = {}
_TEXTURE_CACHE_SIZE = 8


def _textures(world: World) -> RoomTextures:
    """The room textures, drawn once per room and seed (they depend on nothing else)."""
    d = world.door
    key = (float(world.seed), world.room_x_m, world.room_y_m, world.wall_height_m, d.x0_m, d.x1_m, d.height_m)
    tex = _TEXTURES.get(key)
    if tex is None:
        tex = make_textures(world)
        while len(_TEXTURES) >= _TEXTURE_CACHE_SIZE:
            del _TEXTURES[next(iter(_TEXTURES))]
        _TEXTURES[key] = tex
    return tex


def _camera_seed(world: World, camera: CameraSpec) -> int:
    """A per-camera seed for the noise bank (deterministic across processes, unlike ``hash``)."""
    return (world.seed * 1_000_003 + sum((i + 1) * ord(ch) for i, ch in enumerate(camera.id))) % (2**31 - 1) + 1


def light_gain(lighting: LightingSpec, t_s: float) -> float:
    """Global brightness factor at world time ``t_s``: slow drift times the sudden-change level."""
    drift = 1.0 + lighting.drift_amplitude * math.sin(2.0 * math.pi * t_s / lighting.drift_period_s)
    n = bisect.bisect_right(sorted(lighting.sudden_changes_s), t_s)
    return drift * (lighting.sudden_change_gain if n % 2 == 1 else 1.0)


def _scene_primitives(world: World, t_s: float, skip_id: str) -> list[Primitive]:
    prims: list[Primitive] = []
    for k, pl in enumerate(world.platforms_at(t_s)):
        if pl.sensor_id != skip_id:
            prims.extend(platform_primitives(pl, k))
    for p in world.people_at(t_s):
        if p.present:
            prims.extend(person_primitives(p))
    return prims


class _NoiseBank:
    """Per-pixel Gaussian sensor noise without drawing 1.3 M normals per frame.

    Holds twice a frame's worth of N(0, sigma^2) samples (int16), drawn once from
    the seed; each frame adds a contiguous window at a random offset drawn from
    the caller's generator, so every pixel gets a fresh-looking Gaussian value and
    the pattern never stands still from frame to frame, at the cost of one add.
    """

    def __init__(self, shape: tuple[int, ...], sigma: float, seed: int) -> None:
        self.shape = shape
        self.size = int(np.prod(shape))
        self.sigma = float(sigma)
        self.bank = np.empty((2 * self.size, 1), np.int16)
        if self.sigma > 0.0:
            cv2.setRNGSeed(seed)
            cv2.randn(self.bank, np.zeros(1), np.full(1, self.sigma))

    def add(self, img: U8Image, rng: np.random.Generator) -> U8Image:
        if self.sigma <= 0.0:
            return img
        off = int(rng.integers(0, self.size))
        noise = self.bank[off : off + self.size].reshape(self.shape)
        return np.asarray(cv2.add(img, noise, dtype=cv2.CV_8U), dtype=np.uint8)


def _apply_gain(img: U8Image, gain: float | npt.NDArray[np.float32]) -> U8Image:
    if isinstance(gain, float):
        return np.asarray(cv2.convertScaleAbs(img, alpha=gain), dtype=np.uint8)
    return np.clip(img.astype(np.float32) * gain + 0.5, 0, 255).astype(np.uint8)


class PanoramicRenderer:
    """A simulated panoramic (PAL) camera.

    Args:
        world: the simulated world.
        camera: this camera's ``[[camera]]`` entry (kind ``panoramic``).
        lighting: illumination and noise (default: the world's ``[world.lighting]``).
    """

    def __init__(self, world: World, camera: CameraSpec, lighting: LightingSpec | None = None) -> None:
        if camera.kind != "panoramic":
            raise ConfigError(f"camera {camera.id!r}: PanoramicRenderer needs kind 'panoramic', got {camera.kind!r}")
        self.world = world
        self.camera = camera
        self.lighting = lighting if lighting is not None else world.spec.lighting
        iw, ih = camera.image_size
        pw, ph = camera.pano_size
        self._annular, self._cyl = design_pal((iw, ih), (pw, ph), height_m=camera.height_m)
        # The lens sees a little beyond the panorama's rows: render PANO_MARGIN_ROWS extra rows above and
        # below (same cylindrical camera, shifted), so the ring's edges blend real scene, not black.
        m = PANO_MARGIN_ROWS
        cyl = self._cyl
        self._render_cam = CylindricalCamera(
            width_px=pw, height_px=ph + 2 * m, f_v_px=cyl.f_v_px, v0_px=cyl.v0_px + m, height_m=cyl.height_m,
            direction=cyl.direction, bearing0_rad=cyl.bearing0_rad,
        )  # fmt: skip
        yy, xx = np.mgrid[0:ih, 0:iw].astype(np.float64)
        u, v = self._annular.pano_from_annular(xx, yy)
        inside = np.isfinite(v) & (v >= -m + 0.5) & (v <= ph - 1 + m - 0.5)
        map_x = np.where(inside, u, -10.0).astype(np.float32)
        map_y = np.where(inside, v + m, -10.0).astype(np.float32)
        self._map1, self._map2 = cv2.convertMaps(map_x, map_y, cv2.CV_16SC2)
        self._tex = _textures(world)
        cols = np.arange(pw, dtype=np.float64)
        self._theta = np.asarray(cyl.bearing_from_col(cols), dtype=np.float64)[None, :]
        rows = np.arange(ph + 2 * m, dtype=np.float64)
        self._slope = np.tan(np.asarray(self._render_cam.elevation_from_row(rows), dtype=np.float64))[:, None]
        # Lens vignette by panorama row (ring radius): a little darker towards both ring edges.
        rel = (rows - (ph + 2 * m - 1) / 2.0) / max((ph - 1) / 2.0, 1.0)
        self._row_gain = (1.0 - 0.12 * rel * rel).astype(np.float32)[:, None, None]
        self._bg_pose: tuple[float, float, float] | None = None
        self._bg: U8Image | None = None
        self._floor: FloorMap | None = None
        self._noise = _NoiseBank((ih, iw, 3), self.lighting.noise_sigma, _camera_seed(world, camera))

    @property
    def models(self) -> tuple[AnnularModel, CylindricalCamera]:
        """The lens and cylindrical camera models (what a real node has from calibration)."""
        return self._annular, self._cyl

    def _background(self, x_m: float, y_m: float, yaw_rad: float) -> U8Image:
        pose = (x_m, y_m, yaw_rad)
        if self._bg is None or pose != self._bg_pose:
            bearing = self._theta + yaw_rad
            origin = (x_m, y_m, self.camera.height_m)
            img, depth = cast_room(self._tex, origin, np.cos(bearing), np.sin(bearing), self._slope)
            self._bg, self._bg_pose = img, pose
            if self.lighting.shadow_gain < 1.0:
                self._floor = FloorMap.for_view(origin, bearing, self._slope, depth)
        return self._bg

    def render_panorama(self, t_s: float, with_labels: bool = False) -> tuple[U8Image, npt.NDArray[np.int32] | None]:
        """The ideal cylindrical panorama at ``t_s`` (no lighting, no noise) and optionally its label image.

        Both have ``PANO_MARGIN_ROWS`` extra rows above and below the panorama's rows; ``[m:-m]`` is the
        panorama the lens model describes. Labels (see :mod:`sim.render.bodies`) exist for tests and
        debugging only.
        """
        me = self.world.platform_at(self.camera.id, t_s)
        pano = self._background(me.x_m, me.y_m, me.yaw_rad).copy()
        labels = np.zeros(pano.shape[:2], np.int32) if with_labels else None
        view = PanoView(x_m=me.x_m, y_m=me.y_m, z_m=me.z_m, yaw_rad=me.yaw_rad)
        lit = self.lighting
        if self._floor is not None:
            feet = [(p.x_m, p.y_m) for p in self.world.people_at(t_s) if p.present]
            paint_shadows(pano, self._floor, feet, lit.shadow_gain)
        cam_view = (me.x_m, me.y_m, me.z_m, me.yaw_rad)
        paint_plant(pano, self._render_cam, cam_view, self.world.room_y_m, sway_m=lit.sway_m, t_s=t_s)
        paint_primitives(pano, self._render_cam, view, _scene_primitives(self.world, t_s, self.camera.id), labels)
        return pano, labels

    def warp(self, pano: U8Image, interpolation: int = cv2.INTER_LINEAR) -> U8Image:
        """Warp a panorama (or label image) into the annular image; black outside the ring."""
        padded = np.concatenate([pano, pano[:, :1]], axis=1)
        out = cv2.remap(padded, self._map1, self._map2, interpolation, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
        return np.asarray(out, dtype=pano.dtype)

    def render(self, t_s: float, rng: np.random.Generator) -> U8Image:
        """The raw annular BGR image (``image_size``) at world time ``t_s``."""
        pano, _ = self.render_panorama(t_s)
        gain = np.float32(light_gain(self.lighting, t_s)) * self._row_gain
        raw = self.warp(_apply_gain(pano, gain))
        return self._noise.add(raw, rng)


class PtzRenderer:
    """A simulated pan-tilt-zoom camera (perspective image for the current pan, tilt and zoom).

    Args:
        world: the simulated world.
        camera: this camera's ``[[camera]]`` entry (kind ``ptz``); ``height_m`` is the optical centre's height.
        lighting: illumination and noise (default: the world's ``[world.lighting]``).
    """

    def __init__(self, world: World, camera: CameraSpec, lighting: LightingSpec | None = None) -> None:
        if camera.kind != "ptz":
            raise ConfigError(f"camera {camera.id!r}: PtzRenderer needs kind 'ptz', got {camera.kind!r}")
        self.world = world
        self.camera = camera
        self.lighting = lighting if lighting is not None else world.spec.lighting
        self._tex = _textures(world)
        self._state: tuple[float, float, float] | None = None
        self._grid: RayGrid | None = None
        self._bg: tuple[U8Image, npt.NDArray[np.float32]] | None = None
        w, h = camera.image_size
        yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
        r2 = ((xx - (w - 1) / 2) ** 2 + (yy - (h - 1) / 2) ** 2) / (((w - 1) / 2) ** 2 + ((h - 1) / 2) ** 2)
        self._vignette = (1.0 - 0.15 * r2).astype(np.float32)[..., None]
        self._noise = _NoiseBank((h, w, 3), self.lighting.noise_sigma, _camera_seed(world, camera))

    def camera_at(self, pan_rad: float, tilt_rad: float, zoom: float) -> PtzCamera:
        """The PTZ camera model in a given state (pan = world azimuth of the optical axis)."""
        w, h = self.camera.image_size
        return PtzCamera(
            x_m=self.camera.x_m,
            y_m=self.camera.y_m,
            z_m=self.camera.height_m,
            width_px=w,
            height_px=h,
            hfov_rad=math.radians(self.camera.hfov_deg),
            pan_rad=pan_rad,
            tilt_rad=tilt_rad,
            zoom=zoom,
        )

    def _setup(self, pan_rad: float, tilt_rad: float, zoom: float) -> tuple[RayGrid, U8Image, npt.NDArray[np.float32]]:
        state = (pan_rad, tilt_rad, zoom)
        if self._grid is None or self._bg is None or state != self._state:
            pinhole = self.camera_at(pan_rad, tilt_rad, zoom).pinhole()
            w, h = self.camera.image_size
            vv, uu = np.mgrid[0:h, 0:w].astype(np.float64)
            rays = pinhole.ray_world(np.column_stack([uu.ravel(), vv.ravel()]))
            rho = np.maximum(np.hypot(rays[:, 0], rays[:, 1]), 1e-9)
            origin = (self.camera.x_m, self.camera.y_m, self.camera.height_m)
            grid = RayGrid(
                origin_xyz=origin,
                dir_x=(rays[:, 0] / rho).reshape(h, w),
                dir_y=(rays[:, 1] / rho).reshape(h, w),
                slope=(rays[:, 2] / rho).reshape(h, w),
                pinhole=pinhole,
            )
            self._bg = cast_room(self._tex, origin, grid.dir_x, grid.dir_y, grid.slope)
            self._grid, self._state = grid, state
        return self._grid, self._bg[0], self._bg[1]

    def render_clean(self, t_s: float, pan_rad: float, tilt_rad: float, zoom: float) -> U8Image:
        """The image without lighting changes or noise."""
        grid, bg, depth = self._setup(pan_rad, tilt_rad, zoom)
        img, zbuf = bg.copy(), depth.copy()
        paint_primitives_rays(img, zbuf, grid, _scene_primitives(self.world, t_s, self.camera.id))
        return img

    def render(self, t_s: float, pan_rad: float, tilt_rad: float, zoom: float, rng: np.random.Generator) -> U8Image:
        """The BGR image (``image_size``) at world time ``t_s`` for this pan, tilt (rad) and zoom."""
        img = self.render_clean(t_s, pan_rad, tilt_rad, zoom)
        gain = np.float32(light_gain(self.lighting, t_s)) * self._vignette
        return self._noise.add(_apply_gain(img, gain), rng)
