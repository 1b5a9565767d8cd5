"""Feet floor distances of perspective cameras (mono.py), their use against ghosts, and low-rate robustness."""

from __future__ import annotations

import math

import numpy as np
import pytest

from common.schema import Blob, Features, PinholeModel, Pose, SensorInfo
from resource_manager.config import ManagerConfig, ManagerSection
from resource_manager.fusion import Batch, Fusion
from resource_manager.ingest.align import AlignedBlob, AlignedView, AlignParams, align_sensor
from resource_manager.ingest.buffers import Ingest
from resource_manager.mono import mono_measurement, mono_ranges, range_mismatch
from resource_manager.poses.solver import PoseEstimate
from resource_manager.views import build_views

Z_M = 2.5
MONO = (math.radians(0.1), 0.1, 50.0, 1080.0)


def _view_of(
    xy_people: list[tuple[float, float]], cam_xy: tuple[float, float], bottom_px: float = 900.0
) -> AlignedView:
    blobs = []
    for k, (x, y) in enumerate(xy_people):
        d = math.hypot(x - cam_xy[0], y - cam_xy[1])
        blobs.append(
            AlignedBlob(
                local_id=k,
                bearing_rad=math.atan2(y - cam_xy[1], x - cam_xy[0]),
                width_rad=0.45 / d,
                top_elev_rad=math.atan2(1.75 - Z_M, d),
                bottom_elev_rad=math.atan2(-Z_M, d),
                hist=[],
                feet_visible=True,
                bottom_px=bottom_px,
            )
        )
    return AlignedView("c", 0, blobs, [], "held")


@pytest.mark.parametrize(("dist_m", "ok"), [(3.0, True), (20.0, True), (80.0, False)])
def test_mono_ranges_invert_the_feet_elevation(dist_m: float, ok: bool) -> None:
    bottom = np.array([math.atan2(-Z_M, dist_m), np.nan])
    d, s = mono_ranges(bottom, Z_M, math.radians(0.1), 0.1, 50.0)
    assert np.isnan(d[1]) and np.isnan(s[1])  # feet not visible: no distance
    if ok:
        assert d[0] == pytest.approx(dist_m, rel=1e-9)
        # sigma = (D^2 + z^2)/z * sigma_elev + base: grows with the square of the distance
        assert s[0] == pytest.approx((dist_m**2 + Z_M**2) / Z_M * math.radians(0.1) + 0.1)
    else:
        assert np.isnan(d[0])  # beyond max range


def test_views_ignore_feet_of_boxes_cut_by_the_lower_border() -> None:
    poses = {"c": PoseEstimate("c", 0.0, 0.0, Z_M, 0.0, "surveyed")}
    inside = build_views({"c": _view_of([(6.0, 1.0)], (0.0, 0.0))}, poses, lambda _s: 0.0035, mono={"c": MONO})
    cut = build_views(
        {"c": _view_of([(6.0, 1.0)], (0.0, 0.0), bottom_px=1079.0)}, poses, lambda _s: 0.0035, mono={"c": MONO}
    )
    assert inside["c"].mono_range_m is not None and cut["c"].mono_range_m is not None
    assert inside["c"].mono_range_m[0] == pytest.approx(math.hypot(6.0, 1.0))
    assert np.isnan(cut["c"].mono_range_m[0])


def test_a_ghost_crossing_disagrees_with_the_feet_and_one_view_localises() -> None:
    """Two people seen by two cameras: the crossing of A's ray in one camera with B's in the other is a
    ghost whose distance no blob's feet agree with; each camera's own feet give the person's position."""
    people = [(4.0, 3.0), (6.0, 5.0)]
    poses = {
        "a": PoseEstimate("a", 0.0, 0.0, Z_M, 0.0, "surveyed"),
        "b": PoseEstimate("b", 10.0, 0.0, Z_M, 0.0, "surveyed"),
    }
    views = build_views(
        {"a": _view_of(people, (0.0, 0.0)), "b": _view_of(people, (10.0, 0.0))},
        poses,
        lambda _s: 0.0035,
        mono={"a": MONO, "b": MONO},
    )
    a, b = views["a"], views["b"]
    true_xy = np.array(people[0])
    assert range_mismatch(a, 0, true_xy) < 0.1 and range_mismatch(b, 0, true_xy) < 0.1
    # The ghost: ray of person 0 from a, ray of person 1 from b.
    th_a, th_b = float(a.bearing_rad[0]), float(b.bearing_rad[1])
    t = (10.0 * math.sin(th_b)) / math.sin(th_b - th_a)
    ghost = np.array([t * math.cos(th_a), t * math.sin(th_a)])
    assert float(np.hypot(*(ghost - true_xy))) > 1.0
    assert max(range_mismatch(a, 0, ghost), range_mismatch(b, 1, ghost)) > 3.0
    one = mono_measurement([(a, 1)])
    assert one is not None and float(np.hypot(*(one.xy - np.array(people[1])))) < 0.05
    both = mono_measurement([(a, 0), (b, 0)])
    assert both is not None and float(np.hypot(*(both.xy - true_xy))) < 0.05
    assert mono_measurement([]) is None


def test_one_sided_blob_only_from_the_nearer_frame() -> None:
    """At 2 Hz a person whose 2D id changed between frames must not appear twice (old id and new id)."""
    ms = 1_000_000

    def f(seq: int, t_ms: int, lid: int, bearing: float) -> Features:
        b = Blob(
            local_id=lid,
            bearing_rad=bearing,
            width_rad=0.05,
            top_elev_rad=0.1,
            bottom_elev_rad=-0.2,
            bbox_u_px=0,
            bbox_v_px=0,
            bbox_w_px=1,
            bbox_h_px=1,
        )
        return Features(sensor_id="c", seq=seq, stamp_ns=(10_000 + t_ms) * ms, frame_index=seq, blobs=[b])

    ing = Ingest()
    ing.add(f(1, 0, 7, 0.10))
    ing.add(f(2, 500, 8, 0.12))  # same person, new id
    params = AlignParams(max_extrapolation_ns=300 * ms, stale_ns=1500 * ms, max_gap_ns=1250 * ms)
    for t_ms, want in ((0, 7), (100, 7), (400, 8), (500, 8)):
        view = align_sensor(ing.buffers["c"], "c", (10_000 + t_ms) * ms, params)
        assert view is not None
        assert [b.local_id for b in view.blobs] == [want], t_ms


def test_tracks_of_people_who_left_end_at_once_and_unknown_ids_are_bounded() -> None:
    cfg = ManagerConfig(manager=ManagerSection(id="m1"))
    fusion = Fusion(cfg)
    t0 = 1_800_000_000_000_000_000
    k = [1000.0, 0.0, 960.0, 0.0, 1000.0, 540.0, 0.0, 0.0, 1.0]
    cams = {"a": (0.0, 0.0, 0.7853981633974483), "b": (10.0, 0.0, 2.356194490192345), "c": (5.0, 10.0, -1.5707963)}
    infos = []
    for sid, (x, y, yaw) in cams.items():
        # camera looking horizontally along yaw: world -> camera rotation (x right, y down, z forward)
        fwd = (math.cos(yaw), math.sin(yaw), 0.0)
        right = (math.sin(yaw), -math.cos(yaw), 0.0)
        r = [*right, 0.0, 0.0, -1.0, *fwd]
        c = (x, y, Z_M)
        t = [-sum(r[3 * i + j] * c[j] for j in range(3)) for i in range(3)]
        infos.append(
            SensorInfo(
                sensor_id=sid,
                seq=1,
                stamp_ns=t0,
                kind="pinhole",
                model=PinholeModel(width_px=1920, height_px=1080, k=k, r=r, t_m=t),
                pose=Pose(x_m=x, y_m=y, z_m=Z_M, yaw_rad=0.0),
                pose_source="surveyed",
                bearing_sigma_rad=0.0035,
            )
        )
    person = (5.0, 4.0)

    def feats(sid: str, seq: int, t_ns: int, present: bool) -> Features:
        x, y, _ = cams[sid]
        blobs = []
        if present:
            d = math.hypot(person[0] - x, person[1] - y)
            blobs.append(
                Blob(
                    local_id=1,
                    bearing_rad=math.atan2(person[1] - y, person[0] - x),
                    width_rad=0.45 / d,
                    top_elev_rad=math.atan2(1.75 - Z_M, d),
                    bottom_elev_rad=math.atan2(-Z_M, d),
                    bbox_u_px=900,
                    bbox_v_px=300,
                    bbox_w_px=50,
                    bbox_h_px=300,
                )
            )
        return Features(sensor_id=sid, seq=seq, stamp_ns=t_ns, frame_index=seq, blobs=blobs)

    confirmed_at_leave = 0
    for n in range(30):
        t_ns = t0 + n * 250_000_000
        here = n < 20
        batch = Batch(features=[feats(s, n + 1, t_ns, here) for s in cams], infos=infos if n == 0 else [])
        res = fusion.step(batch, t_ns + 1)
        tracks = [tr for tr in res.trackset.tracks if tr.state != "tentative"]
        if n == 19:
            confirmed_at_leave = len(tracks)
            assert math.hypot(tracks[0].x_m - person[0], tracks[0].y_m - person[1]) < 0.1
        if n == 21:
            assert tracks == []  # the views see nobody there any more: gone within a tick, not max_misses later
    assert confirmed_at_leave == 1
    # Made-up sensor ids cannot grow the buffers without bound.
    fakes = [Features(sensor_id=f"fake{i:05d}", seq=1, stamp_ns=t0 + 8_000_000_000, frame_index=1) for i in range(500)]
    fusion.step(Batch(features=fakes), t0 + 8_000_000_001)
    assert len(fusion.ingest.buffers) <= 64
    fusion.step(Batch(), t0 + 12_000_000_000)
    assert set(fusion.ingest.buffers) <= set(cams)  # stale, never announced: forgotten


@pytest.mark.parametrize("kind", ["pinhole", "ptz"])
def test_one_blank_frame_of_every_camera_does_not_end_the_tracks(kind: str) -> None:
    """A sudden light change blanks every camera for a frame: the person is still there (PTZ heads too)."""
    fusion = Fusion(ManagerConfig(manager=ManagerSection(id="m1")))
    t0 = 1_800_000_000_000_000_000
    k = [1000.0, 0.0, 960.0, 0.0, 1000.0, 540.0, 0.0, 0.0, 1.0]
    cams = {"a": (0.0, 0.0, math.pi / 4), "b": (10.0, 0.0, 3 * math.pi / 4), "c": (5.0, 10.0, -math.pi / 2)}
    infos = []
    for sid, (x, y, yaw) in cams.items():
        fwd = (math.cos(yaw), math.sin(yaw), 0.0)
        right = (math.sin(yaw), -math.cos(yaw), 0.0)
        r = [*right, 0.0, 0.0, -1.0, *fwd]
        t = [-sum(r[3 * i + j] * c for j, c in enumerate((x, y, Z_M))) for i in range(3)]
        model = PinholeModel(width_px=1920, height_px=1080, k=k, r=r, t_m=t)
        pose = Pose(x_m=x, y_m=y, z_m=Z_M, yaw_rad=0.0)
        infos.append(SensorInfo(sensor_id=sid, seq=1, stamp_ns=t0, kind=kind, model=model, pose=pose,
                                pose_source="surveyed", bearing_sigma_rad=0.0035))  # fmt: skip
    assert set(fusion._fovs()) == set() and fusion.step(Batch(infos=infos), t0).skipped is False
    assert set(fusion._fovs()) == set(cams) and set(fusion._mono()) == set(cams)  # PTZ heads: their FoV and feet
    person = (5.0, 4.0)

    def feats(sid: str, seq: int, t_ns: int, blank: bool) -> Features:
        x, y, _ = cams[sid]
        d = math.hypot(person[0] - x, person[1] - y)
        blob = Blob(local_id=1, bearing_rad=math.atan2(person[1] - y, person[0] - x), width_rad=0.45 / d,
                    top_elev_rad=math.atan2(1.75 - Z_M, d), bottom_elev_rad=math.atan2(-Z_M, d),
                    bbox_u_px=900, bbox_v_px=300, bbox_w_px=50, bbox_h_px=300)  # fmt: skip
        return Features(sensor_id=sid, seq=seq, stamp_ns=t_ns, frame_index=seq, blobs=[] if blank else [blob])

    ids = []
    for n in range(1, 20):
        t_ns = t0 + n * 250_000_000
        res = fusion.step(Batch(features=[feats(s, n, t_ns, n == 10) for s in cams]), t_ns + 1)
        ids.append([tr.track_id for tr in res.trackset.tracks if tr.state != "tentative"])
    assert ids[8] == ids[9] == ids[10] == ids[-1] == ["m1-1"]
