"""Quality of the image pipeline on rendered, seeded sequences (issue 5, "Quality").

The simulated camera renders pixels; the pipeline sees only those. Ground
truth (the world's people and platforms, and the renderer's label image) is
used here only to score:

* each unoccluded person is detected in >= 95 % of the frames after warm-up;
* the median head-bearing error is <= 1 px;
* no person is reported through a sudden light change (an empty room stays empty);
* mutual calibration (Eq. 3): the baseline is within 3 % at B = 3 m;
* a moving robot body is never reported as a person.

"Unoccluded" means present, at least 1.5 m away (the head is inside the
panorama's 20 deg top) and not overlapping anyone else in bearing.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from common.site import SiteConfig, load_site
from sensor_node.config import BodySpec, PipelineSettings
from sensor_node.features import PanoramicGeometry
from sensor_node.pipeline import ImagePipeline
from sensor_node.unwarp import Unwarper
from sim.render.cameras import PanoramicRenderer
from sim.world import World, sensor_bearing

SITE = """
[site]
name = "quality"
fps = 15.0
seed = {seed}

[world]
room_x_m = 8.0
room_y_m = 6.0
people = {people}
pause_prob = 0.0
person_speed_mps = [0.6, 1.2]

[world.lighting]
noise_sigma = 2.0
drift_amplitude = 0.06
sudden_changes_s = {changes}
sudden_change_gain = 1.35

[[camera]]
id = "cam-a"
x_m = 2.5
y_m = 3.0
yaw_deg = 20.0
band_rgb = [220, 40, 40]

[[camera]]
id = "cam-b"
x_m = 5.5
y_m = 3.0
yaw_deg = 200.0
mobile = {mobile}
waypoints = [[5.5, 4.6], [5.5, 1.4]]
max_speed_mps = 0.4
band_rgb = [40, 80, 220]
"""


def _site(tmp_path: Path, seed: int = 3, people: int = 3, changes: str = "[]", mobile: bool = False) -> SiteConfig:
    p = tmp_path / "site.toml"
    p.write_text(SITE.format(seed=seed, people=people, changes=changes, mobile=str(mobile).lower()))
    return load_site(p)


def _pipeline(site: SiteConfig, cam_id: str) -> tuple[PanoramicRenderer, ImagePipeline, World]:
    world = World.from_site(site)
    renderer = PanoramicRenderer(world, site.camera_by_id(cam_id))
    annular, cyl = renderer.models  # what a real node has from calibration
    bodies = [
        BodySpec(id=c.id, band_rgb=list(c.band_rgb), radius_m=c.body_radius_m, height_m=c.body_height_m)
        for c in site.camera
        if c.id != cam_id
    ]
    # Sightings every frame, so each frame's baseline can be scored against that frame's truth.
    settings = PipelineSettings(sighting_every=1)
    pipe = ImagePipeline(cam_id, PanoramicGeometry(cyl), settings, Unwarper(annular), bodies)
    return renderer, pipe, world


def _col_err(a_rad: float, b_rad: float, f_h: float) -> float:
    return abs(math.atan2(math.sin(a_rad - b_rad), math.cos(a_rad - b_rad))) * f_h


def test_people_detected_and_head_bearings_accurate(tmp_path: Path) -> None:
    site = _site(tmp_path, seed=3, people=3)
    renderer, pipe, world = _pipeline(site, "cam-a")
    cyl = renderer.models[1]
    rng = np.random.default_rng(11)
    seen, total, errors = 0, 0, []
    for k in range(220):
        t = k / site.site.fps
        res = pipe.process(renderer.render(t, rng), stamp_ns=round(k * 1e9 / 15), frame_index=k)
        if res.state != "ok":
            continue
        me = world.platform_at("cam-a", t)
        people = [p for p in world.people_at(t) if p.present]
        objects = [(sensor_bearing(me, p.x_m, p.y_m), math.dist((p.x_m, p.y_m), (me.x_m, me.y_m))) for p in people]
        objects += [
            (sensor_bearing(me, q.x_m, q.y_m), math.dist((q.x_m, q.y_m), (me.x_m, me.y_m)))
            for q in world.platforms_at(t)
            if q.sensor_id != "cam-a"
        ]
        for i, (b, d) in enumerate(objects[: len(people)]):
            # Unoccluded: far enough to have the head in view, clear of everyone else in bearing.
            clear = all(
                _col_err(b, b2, 1.0) > 1.3 * (0.35 / d + 0.35 / d2) for j, (b2, d2) in enumerate(objects) if j != i
            )
            if d < 1.5 or not clear:
                continue
            total += 1
            best = min((_col_err(blob.bearing_rad, b, cyl.f_h_px) for blob in res.features.blobs), default=1e9)
            if best <= 10.0:
                seen += 1
                errors.append(best)
    print(f"detected {seen}/{total}, median err {np.median(errors):.3f} px")
    assert total >= 100, f"too few unoccluded person-frames to score: {total}"
    rate = seen / total
    assert rate >= 0.95, f"detected {seen}/{total} = {rate:.1%} of unoccluded person-frames"
    assert float(np.median(errors)) <= 1.0, f"median head-bearing error {np.median(errors):.2f} px"


def test_no_person_through_a_sudden_light_change(tmp_path: Path) -> None:
    site = _site(tmp_path, seed=5, people=0, changes="[3.0]")
    renderer, pipe, _ = _pipeline(site, "cam-a")
    rng = np.random.default_rng(12)
    states = []
    for k in range(75):
        res = pipe.process(renderer.render(k / 15.0, rng), stamp_ns=round(k * 1e9 / 15), frame_index=k)
        states.append(res.state)
        assert res.features.blobs == [], f"frame {k} ({res.state}): {len(res.features.blobs)} blobs in an empty room"
    assert "relit" in states or "reinit" in states  # the change at 3 s was noticed, not reported
    assert states[-1] == "ok"


@pytest.mark.parametrize("mobile", [False, True])
def test_mutual_calibration_baseline_and_bodies_not_people(tmp_path: Path, mobile: bool) -> None:
    site = _site(tmp_path, seed=7, people=0, mobile=mobile)
    renderer, pipe, world = _pipeline(site, "cam-a")
    rng = np.random.default_rng(13)
    checked = 0
    for k in range(60):
        t = k / 15.0
        res = pipe.process(renderer.render(t, rng), stamp_ns=round(k * 1e9 / 15), frame_index=k)
        me, other = world.platform_at("cam-a", t), world.platform_at("cam-b", t)
        true_b = math.dist((me.x_m, me.y_m), (other.x_m, other.y_m))
        (s,) = res.features.sightings
        assert s.target_id == "cam-b"
        assert abs(s.distance_m - true_b) / true_b <= 0.03, f"t={t:.2f}: B={s.distance_m:.3f} m, true {true_b:.3f} m"
        assert _col_err(s.bearing_rad, sensor_bearing(me, other.x_m, other.y_m), 1.0) < 0.01
        assert res.features.blobs == [], f"t={t:.2f}: the robot body was reported as {len(res.features.blobs)} blob(s)"
        checked += 1
    assert checked == 60
    if not mobile:
        assert abs(s.distance_m - 3.0) / 3.0 <= 0.03


def test_a_person_dressed_like_the_wall_is_one_blob_on_their_head() -> None:
    # paper1's robot camera: the person's shirt and face are within fg_threshold of the wall's grey, so
    # only their hair, trousers and a 1-px outline stand out. The 3 x 3 majority vote erased the outline
    # and the face, leaving the hair and the body below as two blobs, the body's 3 deg off and 8-10 deg
    # wide, which the tracker followed (benchmarks/NOTES.md, issue 14b).
    site = load_site(Path(__file__).resolve().parents[3] / "deploy" / "sites" / "paper1.toml")
    world = World.from_site(site)
    cam = site.camera_by_id("robot")
    renderer = PanoramicRenderer(world, cam)
    annular, cyl = renderer.models
    bodies = [
        BodySpec(id=c.id, band_rgb=list(c.band_rgb), radius_m=c.body_radius_m, height_m=c.body_height_m)
        for c in site.camera
        if c.id != cam.id
    ]
    pipe = ImagePipeline(cam.id, PanoramicGeometry(cyl), PipelineSettings(), Unwarper(annular), bodies, mobile=True)
    rng = np.random.default_rng(1)
    one = on_head = frames = 0
    for k in range(300):
        t = k / site.site.fps
        res = pipe.process(renderer.render(t, rng), stamp_ns=round(t * 1e9), frame_index=k)
        if t < 6.0 or res.state != "ok":
            continue
        frames += 1
        me = world.platform_at(cam.id, t)
        (person,) = [p for p in world.people_at(t) if p.present]
        truth = sensor_bearing(me, person.x_m, person.y_m)
        blobs = res.features.blobs
        one += len(blobs) == 1
        on_head += len(blobs) == 1 and _col_err(blobs[0].bearing_rad, truth, cyl.f_h_px) <= 1.0
    assert frames >= 200
    assert one >= 0.9 * frames, f"one blob in {one}/{frames} frames"  # 0.82 before, 0.87 at 17d3f50
    assert on_head >= 0.85 * frames, f"one blob on the head in {on_head}/{frames} frames"
