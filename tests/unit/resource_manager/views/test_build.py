"""Building views: every sensor's aligned blobs in world terms, known robot bodies are not people, a pinhole camera's
field of view."""

from __future__ import annotations

import math

import msgspec
import numpy as np
import pytest

from common.schema import Blob, Features, PanoramicModel, PinholeModel, SensorInfo
from tests.unit.resource_manager.synth import aligned_of

SIG = math.radians(0.2)


def _blob(lid: int, bearing: float, width: float, top: float, hist: list[float] | None = None) -> Blob:
    """A blob whose box runs from row 10 to row 100, its feet 0.2 rad down."""
    return Blob(
        local_id=lid,
        bearing_rad=bearing,
        width_rad=width,
        top_elev_rad=top,
        bottom_elev_rad=-0.2,
        bbox_u_px=0.0,
        bbox_v_px=10.0,
        bbox_w_px=10.0,
        bbox_h_px=90.0,
        hist=hist or [],
    )


def test_known_bodies_are_not_people() -> None:
    from resource_manager.poses.solver import PoseEstimate
    from resource_manager.views.build import build_views

    def b(lid: int, bearing: float, width: float) -> Blob:
        return _blob(lid, bearing, width, 0.0 if lid == 1 else 0.15)

    poses = {
        "p1": PoseEstimate("p1", 0.0, 0.0, 1.1, 0.0, "surveyed"),
        "r1": PoseEstimate("r1", 3.0, 0.0, 1.1, 0.0, "mutual"),
    }
    # p1 sees r1's body (R = 0.18 m at 3 m: 0.12 rad wide, top at the camera) straight ahead, a person at
    # 0.5 rad, people merged in front of it (wide), and a person right behind it (taller top)
    blobs = [b(1, 0.002, 0.12), b(2, 0.5, 0.1), b(3, 0.01, 0.8), b(4, 0.003, 0.1)]
    av = aligned_of([Features(sensor_id="p1", seq=0, stamp_ns=1, frame_index=0, blobs=blobs)])
    model = PanoramicModel(width_px=1080, height_px=162, f_v_px=256.0, v0_px=93.0)
    robot = SensorInfo(sensor_id="r1", seq=0, stamp_ns=1, kind="panoramic", model=model, body_radius_m=0.18)
    views = build_views(av, poses, {"r1": robot}, lambda s: SIG)
    assert views.sensor_ids == ("p1",) and list(views.local_id) == [2, 3, 4]  # only the body is gone
    bodiless = msgspec.structs.replace(robot, body_radius_m=0.0)
    every = build_views(av, poses, {"r1": bodiless}, lambda s: SIG)
    assert list(every.local_id) == [1, 2, 3, 4]
    assert np.shares_memory(every.width_rad, av.values)  # every blob kept, in order: the aligned arrays, not copied


def test_pinhole_field_of_view() -> None:
    from resource_manager.views.build import pinhole_fov

    # camera looking along world +y, level: R rows are the camera axes in world coordinates
    model = PinholeModel(
        width_px=640, height_px=480, k=[320.0, 0, 320, 0, 320, 240, 0, 0, 1], r=[1.0, 0, 0, 0, 0, -1, 0, 1, 0]
    )
    fov = pinhole_fov(model, margin_rad=0.0)
    assert fov is not None
    assert fov[0] == pytest.approx(math.pi / 2) and fov[1] == pytest.approx(math.pi / 4)
    down = PinholeModel(width_px=640, height_px=480, k=[320.0, 0, 320, 0, 320, 240, 0, 0, 1])  # R = I: looks down z
    assert pinhole_fov(down) is None


def test_world_views_drop_known_bodies_keep_people() -> None:
    """A blob that is another camera's body is dropped; a person behind that body (taller top), a person
    elsewhere and a blob toward a camera without a body are kept; bearings rotate into the world; every
    view keeps its own histograms (none for a sensor that sends none)."""
    from resource_manager.poses.solver import PoseEstimate
    from resource_manager.views.build import build_views

    poses = {
        "a": PoseEstimate("a", 0.0, 0.0, 1.1, 0.3, "surveyed"),
        "b": PoseEstimate("b", 4.0, 0.0, 1.1, 0.0, "surveyed"),
        "c": PoseEstimate("c", 0.0, 4.0, 1.1, -1.0, "surveyed"),
    }
    radius = 0.2

    def seen(sid: str, lid: int, x: float, y: float, top_m: float, width_m: float, hist: list[float]) -> Blob:
        p = poses[sid]
        d = math.hypot(x - p.x_m, y - p.y_m)
        bearing = math.remainder(math.atan2(y - p.y_m, x - p.x_m) - p.yaw_rad, 2 * math.pi)
        top = math.atan2(top_m - p.z_m, d)
        return _blob(lid, bearing, 2 * math.asin(width_m / 2 / d), top, hist)

    h1, h2, h3 = [0.5, 0.5, 0.0], [0.2, 0.3, 0.5], [1.0, 0.0, 0.0]
    blobs = {
        # a sees b's body (top at b's camera), a person behind b, a person elsewhere
        "a": [
            seen("a", 1, 4.0, 0.0, 1.0, 0.4, h1),
            seen("a", 2, 6.0, 0.0, 1.8, 0.45, h2),
            seen("a", 3, 2.0, 3.0, 1.7, 0.45, h3),
        ],
        # b sees c's body and camera a (no body: kept)
        "b": [seen("b", 7, 0.0, 4.0, 1.0, 0.4, h1), seen("b", 8, 0.0, 0.0, 1.0, 0.3, h2)],
        # c sends no histograms
        "c": [seen("c", 4, 2.0, 3.0, 1.7, 0.45, []), seen("c", 5, 4.0, 0.0, 1.0, 0.4, [])],
    }  # fmt: skip
    # Given in another order than the sensor ids': the views come in order of sensor ids.
    aligned = aligned_of([Features(sensor_id=s, seq=0, stamp_ns=1, frame_index=0, blobs=blobs[s]) for s in "cab"])
    model = PanoramicModel(width_px=1080, height_px=162, f_v_px=256.0, v0_px=93.0)

    def info(sid: str, body_m: float) -> SensorInfo:
        return SensorInfo(sensor_id=sid, seq=0, stamp_ns=1, kind="panoramic", model=model, body_radius_m=body_m)

    infos = {"a": info("a", 0.0), "b": info("b", radius), "c": info("c", radius)}
    views = build_views(aligned, poses, infos, lambda sid: 0.002)
    assert views.sensor_ids == ("a", "b", "c")
    assert views.local_id[views.span(0)].tolist() == [2, 3]  # b's body dropped, the person behind it kept
    assert views.local_id[views.span(1)].tolist() == [8]  # c's body dropped, camera a has no body
    assert views.local_id[views.span(2)].tolist() == [4]  # b's body dropped
    for row, sid in enumerate(views.sensor_ids):
        span = views.span(row)
        kept = [b for b in blobs[sid] if b.local_id in views.local_id[span].tolist()]
        world = [math.remainder(b.bearing_rad + poses[sid].yaw_rad, 2 * math.pi) for b in kept]
        bearing = views.bearing_rad[span]
        assert np.allclose(np.remainder(bearing - world + math.pi, 2 * math.pi) - math.pi, 0.0, atol=1e-12)
        assert views.width_rad[span].tolist() == [b.width_rad for b in kept]
        assert views.sigma_rad[row] == pytest.approx(0.002)
        if sid == "c":
            assert views.hist_bins[row] == 0
        else:
            assert views.hist_bins[row] == 3
            assert np.allclose(views.hist_sqrt[3][span] ** 2, [b.hist for b in kept])
    # Without bodies nothing is dropped.
    views = build_views(aligned, poses, {}, lambda sid: 0.002)
    assert views.counts.tolist() == [3, 2, 2]
    # A sensor skipped this instant (a robot not settled) gives no view.
    assert build_views(aligned, poses, {}, lambda sid: 0.002, skip={"b"}).sensor_ids == ("a", "c")
