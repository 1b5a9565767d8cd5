"""Head bearings on rendered frames: no bias from the face/hair contrast, people side by side apart.

The simulated camera renders pixels; the test places the people (it controls
the scene) and uses their true positions only to score the blobs the
pipeline reports.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np

from common.site import load_site
from sensor_node.config import PipelineSettings
from sensor_node.features import PanoramicGeometry
from sensor_node.pipeline import ImagePipeline
from sensor_node.unwarp import Unwarper
from sim.render.cameras import PanoramicRenderer
from sim.world import PersonState, World, sensor_bearing

SITE = """
[site]
name = "heads"
fps = 15.0
seed = 5

[world]
room_x_m = 8.0
room_y_m = 8.0
people = {people}
person_height_m = [1.7, 1.8]

[world.lighting]
noise_sigma = 2.0
drift_amplitude = 0.0

[[camera]]
id = "cam"
x_m = 1.0
y_m = 1.0
yaw_deg = 30.0
body_radius_m = 0.0
"""

WARMUP = 40
"""Frames of an empty room first (the background model learns it)."""


class _Staged:
    """The world's people, placed by the test: absent while warming up, then at ``place(k, i)``."""

    def __init__(self, world: World, place: object) -> None:
        self.base = world.people_at(0.0)
        self.place = place
        self.frame = 0

    def people_at(self, t_s: float) -> list[PersonState]:
        out = []
        for i, p in enumerate(self.base):
            if self.frame < WARMUP:
                out.append(dataclasses.replace(p, present=False))
                continue
            x, y, heading, speed = self.place(self.frame - WARMUP, i)  # type: ignore[operator]
            out.append(
                dataclasses.replace(
                    p, x_m=x, y_m=y, heading_rad=heading, speed_mps=speed, gait_phase_rad=0.4 * self.frame, present=True
                )
            )
        return out


def _run(tmp_path: Path, people: int, place: object, frames: int) -> list[tuple[list[float], list[float], float]]:
    """(true bearings, reported bearings, f_h) of each frame after the warm-up."""
    path = tmp_path / "site.toml"
    path.write_text(SITE.format(people=people))
    site = load_site(path)
    world = World.from_site(site)
    staged = _Staged(world, place)
    world.people_at = staged.people_at  # type: ignore[method-assign]
    renderer = PanoramicRenderer(world, site.camera_by_id("cam"))
    annular, cyl = renderer.models
    pipe = ImagePipeline("cam", PanoramicGeometry(cyl), PipelineSettings(), Unwarper(annular))
    rng = np.random.default_rng(3)
    me = world.platform_at("cam", 0.0)
    out = []
    for k in range(WARMUP + frames):
        staged.frame = k
        t = k / 15.0
        res = pipe.process(renderer.render(t, rng), stamp_ns=round(k * 1e9 / 15), frame_index=k)
        if k < WARMUP + 3:
            continue
        truth = [sensor_bearing(me, p.x_m, p.y_m) for p in world.people_at(t) if p.present]
        out.append((truth, [b.bearing_rad for b in res.features.blobs], cyl.f_h_px))
    return out


def _err_px(a: float, b: float, f_h: float) -> float:
    return math.atan2(math.sin(a - b), math.cos(a - b)) * f_h


def test_head_bearing_unbiased_when_the_face_is_seen_side_on(tmp_path: Path) -> None:
    # One person walking across the view at 3.5 m (profile view: hair on one side of the head,
    # the face -- low contrast against the wall -- on the other), both directions.
    def place(k: int, i: int) -> tuple[float, float, float, float]:
        d, b = 3.5, math.radians(30.0 + 45.0)
        heading = b + (math.pi / 2 if k < 20 else -math.pi / 2)
        s = 0.04 * (k if k < 20 else 40 - k)
        return 1.0 + d * math.cos(b) - s * math.sin(b), 1.0 + d * math.sin(b) + s * math.cos(b), heading, 0.6

    errs = []
    for truth, got, f_h in _run(tmp_path, 1, place, 40):
        assert len(got) == 1, f"{len(got)} blobs for one person"
        errs.append(_err_px(got[0], truth[0], f_h))
    e = np.asarray(errs)
    print(f"bias {e.mean():+.3f} px, median |error| {np.median(np.abs(e)):.3f} px over {e.size} frames")
    assert abs(float(e.mean())) <= 0.12, f"head bearing bias {e.mean():+.3f} px"
    assert float(np.median(np.abs(e))) <= 0.2, f"median |error| {np.median(np.abs(e)):.3f} px"


def test_two_people_side_by_side_are_two_blobs_with_their_own_heads(tmp_path: Path) -> None:
    # Two people 0.5 m apart, shoulder to shoulder, 3 m from the camera, walking slowly side by side
    # away from it: grouping joins them (their arms touch); the split must part them at the heads.
    def place(k: int, i: int) -> tuple[float, float, float, float]:
        b = math.radians(30.0 + 60.0)
        d = 3.0 + 0.03 * k
        lateral = (i - 0.5) * 0.5
        return 1.0 + d * math.cos(b) - lateral * math.sin(b), 1.0 + d * math.sin(b) + lateral * math.cos(b), b, 0.45

    good = 0
    runs = _run(tmp_path, 2, place, 24)
    for truth, got, f_h in runs:
        if len(got) != 2:
            continue
        errs = [min(abs(_err_px(g, t, f_h)) for g in got) for t in truth]
        good += max(errs) <= 1.0
    print(f"{good}/{len(runs)} frames with two blobs, both heads within 1 px")
    assert good >= 0.9 * len(runs), f"two blobs with both heads within 1 px in {good}/{len(runs)} frames"
