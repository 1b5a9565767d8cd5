"""Simulated cameras: people and robots appear where the camera models say; light and noise behave."""

from __future__ import annotations

import math

import cv2
import msgspec
import numpy as np
import pytest

from common.cameras import AnnularModel
from common.errors import ConfigError
from common.site import CameraSpec, LightingSpec, SiteConfig, load_site
from sim.render.bodies import PLATFORM_LABEL0, band_z_range, head_size
from sim.render.cameras import PANO_MARGIN_ROWS, PanoramicRenderer, PtzRenderer, light_gain
from sim.world import PersonState, World, sensor_bearing
from tests.support import REPO

SITES = REPO / "deploy" / "sites"
CLEAN = LightingSpec(noise_sigma=0.0, drift_amplitude=0.0)


def _site(name: str) -> SiteConfig:
    return load_site(SITES / f"{name}.toml")


def _without_people(site: SiteConfig, keep_camera: str | None = None) -> SiteConfig:
    world = msgspec.structs.replace(site.world, people=0)
    cams = site.camera if keep_camera is None else [c for c in site.camera if c.id == keep_camera]
    return msgspec.structs.replace(site, world=world, camera=cams)


def _unwarp(annular: AnnularModel, img: np.ndarray, interp: int = cv2.INTER_LINEAR) -> np.ndarray:
    map_x, map_y = annular.unwarp_maps()
    return cv2.remap(img, map_x, map_y, interp)


def _occluded(world: World, cam_id: str, t_s: float, person_id: int, f_h: float) -> bool:
    """Whether anything nearer than the person's head comes within a few pixels of it in bearing."""
    me = world.platform_at(cam_id, t_s)
    people = {p.person_id: p for p in world.people_at(t_s) if p.present}
    target = people[person_id]
    d = math.hypot(target.x_m - me.x_m, target.y_m - me.y_m)
    b = sensor_bearing(me, target.x_m, target.y_m)
    half = math.asin(min(1.0, 0.1 / d)) + 3.0 / f_h
    others = [(p.x_m, p.y_m, 0.45) for pid, p in people.items() if pid != person_id]
    others += [(pl.x_m, pl.y_m, max(pl.radius_m, 0.08)) for pl in world.platforms_at(t_s) if pl.sensor_id != cam_id]
    for x, y, r in others:
        d_o = math.hypot(x - me.x_m, y - me.y_m)
        if d_o >= d + 0.3 or d_o <= r:
            continue
        sep = abs((sensor_bearing(me, x, y) - b + math.pi) % (2 * math.pi) - math.pi)
        if sep < half + math.asin(r / d_o):
            return True
    return False


CASES = [("demo", "pano1", 5.0), ("demo", "pano2", 12.0), ("demo", "pano3", 31.0), ("six", "cam2", 7.0)]
CASES += [("crowd", "post1", 40.0), ("paper2", "robot", 9.0)]


@pytest.mark.parametrize(("name", "cam_id", "t_s"), CASES)
def test_head_bearing_from_rendered_pixels_matches_the_camera_model(name: str, cam_id: str, t_s: float) -> None:
    """Each unoccluded head's silhouette, measured in the unwarped raw frame, is centred within 1 px of
    col_from_bearing(true head bearing)."""
    site = _site(name)
    cam = site.camera_by_id(cam_id)
    world = World.from_site(site)
    rend = PanoramicRenderer(world, cam, CLEAN)
    empty = PanoramicRenderer(World.from_site(_without_people(site)), cam, CLEAN)
    annular, cyl = rend.models
    rng = np.random.default_rng(0)
    frame = _unwarp(annular, rend.render(t_s, rng)).astype(np.int32)
    room = _unwarp(annular, empty.render(t_s, rng)).astype(np.int32)
    changed = np.abs(frame - room).sum(axis=2) > 24
    # Which pixels belong to whom: the label image, through the same warp and unwarp (nearest).
    _, labels = rend.render_panorama(t_s, with_labels=True)
    assert labels is not None
    lab = _unwarp(annular, rend.warp(labels.astype(np.float32), cv2.INTER_NEAREST), cv2.INTER_NEAREST)
    me = world.platform_at(cam_id, t_s)
    checked = 0
    for p in world.people_at(t_s):
        if not p.present or _occluded(world, cam_id, t_s, p.person_id, cyl.f_h_px):
            continue
        truth = float(cyl.col_from_bearing(sensor_bearing(me, p.x_m, p.y_m)))
        region = cv2.dilate((lab == 2 * p.person_id).astype(np.uint8), np.ones((3, 3), np.uint8)) > 0
        rows, cols = np.nonzero(region & changed)
        if rows.size < 8:
            continue  # head above the field of view (very close) or too small to measure
        offs = (cols - truth + cyl.width_px / 2) % cyl.width_px - cyl.width_px / 2
        assert abs(float(offs.mean())) <= 1.0, (name, cam_id, p.person_id, float(offs.mean()))
        checked += 1
    assert checked >= 1


def _edges_at_half_contrast(profile: np.ndarray, offsets: np.ndarray) -> tuple[float, float]:
    """Sub-pixel left/right crossings of 0.5 of a 0..1 profile peaked in the middle."""
    mid = profile.size // 2
    i = int(np.flatnonzero(profile[:mid] < 0.5).max())
    left = offsets[i] + (0.5 - profile[i]) / (profile[i + 1] - profile[i])
    j = mid + int(np.flatnonzero(profile[mid:] < 0.5).min())
    right = offsets[j - 1] + (profile[j - 1] - 0.5) / (profile[j - 1] - profile[j])
    return float(left), float(right)


def test_robot_cylinders_span_the_bearings_eq3_predicts() -> None:
    """Occluding boundaries of each other body at centre +- asin(R/B) (Eq. 3: B = R / sin(alpha/2)),
    both in the ideal panorama and, sub-pixel, in the unwarped raw frame."""
    site = _site("demo")
    world = World.from_site(site)
    checked = 0
    for cam in (c for c in site.camera if c.kind == "panoramic"):
        rend = PanoramicRenderer(world, cam, CLEAN)
        bare = PanoramicRenderer(World.from_site(_without_people(site, keep_camera=cam.id)), cam, CLEAN)
        annular, cyl = rend.models
        t_s = 0.0
        frame = _unwarp(annular, rend.render(t_s, np.random.default_rng(0))).astype(float)
        room = _unwarp(annular, bare.render(t_s, np.random.default_rng(0))).astype(float)
        _, labels = rend.render_panorama(t_s, with_labels=True)
        assert labels is not None
        labels = labels[PANO_MARGIN_ROWS:-PANO_MARGIN_ROWS]
        me = world.platform_at(cam.id, t_s)
        assert not (labels == PLATFORM_LABEL0 + site.camera.index(cam)).any()  # own body never in own view
        for k, pl in enumerate(world.platforms_at(t_s)):
            if pl.sensor_id == cam.id or pl.radius_m <= 0:
                continue
            b_m = math.hypot(pl.x_m - me.x_m, pl.y_m - me.y_m)
            centre = float(cyl.col_from_bearing(sensor_bearing(me, pl.x_m, pl.y_m)))
            half_px = math.asin(pl.radius_m / b_m) * cyl.f_h_px
            row = round(float(cyl.row_from_elevation(math.atan2(0.85 * pl.body_height_m - me.z_m, b_m))))
            if not 0 <= row < cyl.height_px:
                continue
            # Ideal panorama: the pixels the body covers at least half.
            cols = np.flatnonzero(labels[row] == PLATFORM_LABEL0 + k)
            offs = (cols - centre + cyl.width_px / 2) % cyl.width_px - cyl.width_px / 2
            assert offs.min() - 0.5 == pytest.approx(-half_px, abs=0.75)
            assert offs.max() + 0.5 == pytest.approx(half_px, abs=0.75)
            # Raw frame through the lens and back: half-contrast crossings of the white body.
            span = np.arange(round(centre) - 30, round(centre) + 31)
            diff = np.abs(frame[row, span % cyl.width_px] - room[row, span % cyl.width_px]).sum(axis=1)
            inner = diff[30 - int(half_px) + 3 : 30 + int(half_px) - 2]
            assert inner.min() > 60  # the white body stands out from the room
            left, right = _edges_at_half_contrast(diff / inner.mean(), span - centre)
            assert left == pytest.approx(-half_px, abs=1.0) and right == pytest.approx(half_px, abs=1.0)
            alpha = (right - left) / cyl.f_h_px
            assert pl.radius_m / math.sin(alpha / 2) == pytest.approx(b_m, rel=0.06)
            # White above the band; the band shows its colour (BGR order in the image).
            white = frame[row, round(centre) % cyl.width_px]
            assert white.min() > 190 and white.max() - white.min() < 30
            z0, z1 = band_z_range(pl.body_height_m)
            row_band = round(float(cyl.row_from_elevation(math.atan2(0.5 * (z0 + z1) - me.z_m, b_m))))
            if row_band < cyl.height_px:
                band = frame[row_band, round(centre) % cyl.width_px]
                assert np.argmax(band) == np.argmax(pl.band_rgb[::-1])
            checked += 1
    assert checked >= 5


def test_moving_robot_sees_the_world_from_where_it_is() -> None:
    site = _site("demo")
    world = World.from_site(site)
    world.set_goal("pano1", 3.5, 1.2, issued_s=1.0)
    cam = site.camera_by_id("pano1")
    rend = PanoramicRenderer(world, cam, CLEAN)
    _, cyl = rend.models
    seen = []
    for t_s in (0.5, 3.0, 6.0):
        _, labels = rend.render_panorama(t_s, with_labels=True)
        assert labels is not None
        labels = labels[PANO_MARGIN_ROWS:-PANO_MARGIN_ROWS]
        me = world.platform_at("pano1", t_s)
        assert me.x_m != 2.2 or t_s < 1.0
        checked = 0
        for k, other in enumerate(world.platforms_at(t_s)):
            if other.sensor_id not in ("pano2", "pano3"):
                continue
            b_m = math.hypot(other.x_m - me.x_m, other.y_m - me.y_m)
            centre = float(cyl.col_from_bearing(sensor_bearing(me, other.x_m, other.y_m)))
            cols = np.flatnonzero((labels == PLATFORM_LABEL0 + k).any(axis=0))
            if cols.size < 2 * math.asin(other.radius_m / b_m) * cyl.f_h_px - 1:
                continue  # partly hidden behind someone
            offs = (cols - centre + cyl.width_px / 2) % cyl.width_px - cyl.width_px / 2
            assert abs(0.5 * (offs.min() + offs.max())) <= 1.0
            checked += 1
            if other.sensor_id == "pano2":
                seen.append(centre)
        assert checked >= 1
    assert len(seen) >= 2 and abs(seen[0] - seen[-1]) > 5  # it moved, and the view moved with it


def test_sudden_light_change_and_drift_change_global_brightness() -> None:
    site = _site("demo")
    lighting = msgspec.structs.replace(site.world.lighting, noise_sigma=0.0)
    cam = site.camera_by_id("pano3")
    rend = PanoramicRenderer(World.from_site(_without_people(site)), cam, lighting)
    rng = np.random.default_rng(0)
    before = rend.render(19.9, rng).astype(float)
    after = rend.render(20.1, rng).astype(float)
    ring = before.sum(axis=2) > 30
    ratio = after[ring].mean() / before[ring].mean()
    expect = light_gain(lighting, 20.1) / light_gain(lighting, 19.9)
    assert expect == pytest.approx(1.35, abs=0.01)
    assert ratio == pytest.approx(expect, rel=0.06)  # a few bright pixels saturate
    slow = rend.render(10.0, rng).astype(float)[ring].mean() / rend.render(0.0, rng).astype(float)[ring].mean()
    assert slow == pytest.approx(light_gain(lighting, 10.0) / light_gain(lighting, 0.0), rel=0.02)
    # One change so far: the light stays up (the next change would bring it back).
    assert light_gain(lighting, 45.0) == pytest.approx(1.35 * (1.0 + 0.06 * math.sin(2 * math.pi * 45 / 40)), rel=1e-9)


def test_same_seed_and_time_same_image_and_noise_has_the_configured_sigma() -> None:
    site = _site("demo")
    cam = site.camera_by_id("pano2")
    a = PanoramicRenderer(World.from_site(site), cam).render(7.0, np.random.default_rng(5))
    b = PanoramicRenderer(World.from_site(site), cam).render(7.0, np.random.default_rng(5))
    assert a.shape == (576, 768, 3) and a.dtype == np.uint8
    assert np.array_equal(a, b)
    c = PanoramicRenderer(World.from_site(site), cam).render(7.0, np.random.default_rng(6))
    mid = (a > 12) & (a < 243) & (c > 12) & (c < 243)
    diff = a.astype(float) - c.astype(float)
    assert diff[mid].std() == pytest.approx(site.world.lighting.noise_sigma * math.sqrt(2), rel=0.1)
    later = PanoramicRenderer(World.from_site(site), cam).render(7.5, np.random.default_rng(5))
    assert np.abs(later.astype(float) - a.astype(float)).mean() > 1.0


def test_annular_frame_is_a_ring() -> None:
    site = _site("demo")
    rend = PanoramicRenderer(World.from_site(site), site.camera_by_id("pano1"), CLEAN)
    img = rend.render(0.0, np.random.default_rng(0))
    annular, _ = rend.models
    r_in, r_out = annular.radius_range_px
    yy, xx = np.mgrid[0:576, 0:768]
    r = np.hypot(xx - annular.cx_px, yy - annular.cy_px)
    assert img[r < r_in - 3].max() == 0 and img[r > r_out + 3].max() == 0
    assert img[(r > r_in + 3) & (r < r_out - 3)].min(axis=1).mean() > 40


def test_ptz_frame_shows_people_and_robots_where_the_pinhole_model_projects_them() -> None:
    site = _site("demo")
    cam = site.camera_by_id("ptz1")
    world = World.from_site(site)
    rend = PtzRenderer(world, cam, CLEAN)
    empty = PtzRenderer(World.from_site(_without_people(site)), cam, CLEAN)
    pan, tilt = math.radians(cam.pan_deg), math.radians(cam.tilt_deg)
    pin = rend.camera_at(pan, tilt, 1.0).pinhole()
    hits = 0
    for t_s in (2.0, 9.0, 16.0):
        img = rend.render(t_s, pan, tilt, 1.0, np.random.default_rng(0)).astype(int)
        bg = empty.render(t_s, pan, tilt, 1.0, np.random.default_rng(0)).astype(int)
        assert img.shape == (480, 640, 3)
        changed = np.abs(img - bg).sum(axis=2) > 30
        for p in world.people_at(t_s):
            _, rv = head_size(p.height_m)
            uv, front = pin.project(np.array([[p.x_m, p.y_m, p.height_m - rv]]))
            u, v = float(uv[0, 0]), float(uv[0, 1])
            if (
                not p.present
                or not front[0]
                or not (5 <= u < 635 and 5 <= v < 475)
                or _occluded_ptz(world, cam, p, t_s)
            ):
                continue
            assert changed[round(v), round(u)]
            hits += 1
    assert hits >= 3
    # A robot's band is at the projected band height on its axis.
    pl = world.platform_at("pano3", 0.0)
    z0, z1 = band_z_range(pl.body_height_m)
    uv, front = pin.project(np.array([[pl.x_m, pl.y_m, 0.5 * (z0 + z1)]]))
    assert front[0]
    img = rend.render(0.0, pan, tilt, 1.0, np.random.default_rng(0))
    px = img[round(uv[0, 1]), round(uv[0, 0])]
    assert np.argmax(px) == 1  # green band, BGR
    with pytest.raises(ConfigError):
        PtzRenderer(world, site.camera_by_id("pano1"))
    with pytest.raises(ConfigError):
        PanoramicRenderer(world, cam)


def _occluded_ptz(world: World, cam: CameraSpec, person: PersonState, t_s: float) -> bool:
    """Anyone or any body between the PTZ camera and this person's head (in azimuth, nearer)."""
    px, py = person.x_m, person.y_m
    d = math.hypot(px - cam.x_m, py - cam.y_m)
    b = math.atan2(py - cam.y_m, px - cam.x_m)
    things = [(q.x_m, q.y_m, 0.45) for q in world.people_at(t_s) if q.present and q.person_id != person.person_id]
    things += [(pl.x_m, pl.y_m, pl.radius_m + 0.05) for pl in world.platforms_at(t_s) if pl.radius_m > 0]
    for x, y, r in things:
        d_o = math.hypot(x - cam.x_m, y - cam.y_m)
        if d_o < d and d_o > r:
            sep = abs((math.atan2(y - cam.y_m, x - cam.x_m) - b + math.pi) % (2 * math.pi) - math.pi)
            if sep < math.asin(r / d_o) + math.asin(0.12 / d):
                return True
    return False
