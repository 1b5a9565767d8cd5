"""The simulated camera source: frame k shows world time k / fps, stamped on the common epoch; seeded noise."""

from __future__ import annotations

import math
import threading

import msgspec
import numpy as np
import pytest

from common.site import CameraSpec, SiteConfig, SiteSection, WorldSpec
from sim.render.cameras import PanoramicRenderer
from sim.source import SimFrames, noise_seed

EPOCH_NS = 1_700_000_000_000_000_000
SMALL = {"image_size": [192, 144], "pano_size": [270, 40]}


def _site() -> SiteConfig:
    cams = [
        CameraSpec(id="pano1", x_m=2.0, y_m=2.0, **SMALL),  # type: ignore[arg-type]
        CameraSpec(id="ptz1", kind="ptz", x_m=0.1, y_m=0.1, height_m=2.5, pan_deg=45.0, tilt_deg=-20.0, zoom=2.0),
    ]
    spec = msgspec.convert({"room_x_m": 6.0, "room_y_m": 5.0, "people": 2}, WorldSpec)
    return SiteConfig(site=SiteSection(name="t", seed=9, fps=4.0), world=spec, camera=cams)


def _source(now_ns: int, seed: int = -1) -> SimFrames:
    return SimFrames(_site(), "pano1", fps=0.0, epoch_ns=EPOCH_NS, seed=seed, clock=lambda: now_ns)


def test_a_frame_shows_the_world_at_its_slot_stamped_on_the_common_epoch() -> None:
    src = _source(EPOCH_NS + 2_600_000_000)  # 2.6 s after the epoch; the site's 4 fps
    frame = src.read(threading.Event())
    assert frame is not None and frame.image is not None
    assert frame.index == 11 and frame.stamp_ns == EPOCH_NS + 2_750_000_000  # the next slot, 11 / 4 s
    assert frame.image.shape == (144, 192, 3) and src.state == "ok"
    clean = PanoramicRenderer(src.world, src.spec, msgspec.structs.replace(src.site.world.lighting, noise_sigma=0.0))
    reference = clean.render(11 / 4.0, np.random.default_rng(0)).astype(float)
    ring = reference.sum(axis=2) > 0
    diff = np.abs(frame.image.astype(float) - reference)[ring]
    assert diff.mean() < 2.5 and np.percentile(diff, 99) < 10  # noise only (sigma 2): the same instant
    assert frame.ptz is None


def test_same_seed_same_frame_another_seed_other_noise() -> None:
    now = EPOCH_NS + 1_000_000_000
    frames = [_source(now, seed).read(threading.Event()) for seed in (5, 5, 6)]
    images = [f.image for f in frames if f is not None and f.image is not None]
    assert len(images) == 3
    assert np.array_equal(images[0], images[1]) and not np.array_equal(images[0], images[2])


def test_a_stopped_source_waiting_for_its_first_slot_gives_no_frame() -> None:
    stop = threading.Event()
    stop.set()
    assert _source(EPOCH_NS - 5_000_000_000).read(stop) is None  # the epoch is 5 s ahead


def test_noise_seeds_differ_by_site_and_camera_unless_given() -> None:
    assert len({noise_seed(s, c) for s, c in [(1, "pano1"), (1, "pano2"), (2, "pano1")]}) == 3
    assert noise_seed(1, "pano1") == noise_seed(1, "pano1")  # the same in every process (not hash())
    assert noise_seed(1, "pano1", seed=17) == noise_seed(2, "pano2", seed=17) == 17


def test_a_ptz_source_gives_the_heads_camera_in_its_configured_pointing() -> None:
    src = SimFrames(_site(), "ptz1", fps=2.0, epoch_ns=EPOCH_NS, seed=-1, clock=lambda: EPOCH_NS)
    cam = src.ptz_camera(0.1, 0.1, 2.5)
    assert src.kind == "ptz" and src.fps == 2.0
    assert (cam.pan_rad, cam.tilt_rad, cam.zoom) == pytest.approx((math.pi / 4, math.radians(-20.0), 2.0))
    assert (cam.width_px, cam.height_px) == tuple(src.spec.image_size)
