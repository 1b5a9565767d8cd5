"""Feet floor distances of perspective cameras (views/mono.py), their use against ghosts, and low-rate robustness."""

from __future__ import annotations

import math

import numpy as np
import pytest

from common.schema import Blob, Features, PinholeModel, Pose, SensorInfo
from resource_manager.config import ManagerConfig, ManagerSection
from resource_manager.fusion import Batch, Fusion
from resource_manager.ingest.align import Aligned, AlignParams, align
from resource_manager.ingest.buffers import Ingest
from resource_manager.poses.solver import PoseEstimate
from resource_manager.views.build import FeetModel, build_views
from resource_manager.views.mono import mono_ranges
from tests.unit.resource_manager.synth import aligned_of

Z_M = 2.5
FEET = FeetModel(math.radians(0.1), 0.1, 50.0)
K = [1000.0, 0.0, 960.0, 0.0, 1000.0, 540.0, 0.0, 0.0, 1.0]


def _pinhole_info(sid: str, x: float, y: float, yaw: float, kind: str = "pinhole") -> SensorInfo:
    """A 1920x1080 camera at (x, y, Z_M) looking horizontally along ``yaw``."""
    fwd = (math.cos(yaw), math.sin(yaw), 0.0)
    right = (math.sin(yaw), -math.cos(yaw), 0.0)
    r = [*right, 0.0, 0.0, -1.0, *fwd]  # world -> camera rows: x right, y down, z forward
    t = [-sum(r[3 * i + j] * c for j, c in enumerate((x, y, Z_M))) for i in range(3)]
    model = PinholeModel(width_px=1920, height_px=1080, k=K, r=r, t_m=t)
    pose = Pose(x_m=x, y_m=y, z_m=Z_M, yaw_rad=0.0)
    return SensorInfo(sensor_id=sid, seq=1, stamp_ns=0, kind=kind, model=model, pose=pose,  # type: ignore[arg-type]
                      pose_source="surveyed", bearing_sigma_rad=0.0035)  # fmt: skip


def _view_of(xy_people: list[tuple[float, float]], cam_xy: tuple[float, float], bottom_px: float = 900.0) -> Aligned:
    blobs = []
    for k, (x, y) in enumerate(xy_people):
        d = math.hypot(x - cam_xy[0], y - cam_xy[1])
        blobs.append(
            Blob(
                local_id=k,
                bearing_rad=math.atan2(y - cam_xy[1], x - cam_xy[0]),
                width_rad=0.45 / d,
                top_elev_rad=math.atan2(1.75 - Z_M, d),
                bottom_elev_rad=math.atan2(-Z_M, d),
                bbox_u_px=900.0,
                bbox_v_px=600.0,
                bbox_w_px=50.0,
                bbox_h_px=bottom_px - 600.0,
            )
        )
    return aligned_of([Features(sensor_id="c", seq=0, stamp_ns=1, frame_index=0, blobs=blobs)])


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
    infos = {"c": _pinhole_info("c", 0.0, 0.0, 0.0)}
    inside = build_views(_view_of([(6.0, 1.0)], (0.0, 0.0)), poses, infos, lambda _s: 0.0035, feet=FEET)
    cut = build_views(_view_of([(6.0, 1.0)], (0.0, 0.0), bottom_px=1079.0), poses, infos, lambda _s: 0.0035, feet=FEET)
    none = build_views(_view_of([(6.0, 1.0)], (0.0, 0.0)), poses, infos, lambda _s: 0.0035, feet=None)
    assert inside.mono_range_m[0] == pytest.approx(math.hypot(6.0, 1.0))
    assert np.isnan(cut.mono_range_m[0])
    assert np.isnan(none.mono_range_m).all()  # feet_sigma_deg = 0: no distances
    assert inside.image[0] is not None and inside.fov[0] is not None  # it knows what it can see


def test_the_feet_tell_people_from_ghosts_of_crossing_rays() -> None:
    """Two people seen by two perspective cameras: their rays cross at two ghosts as well. The feet give each
    blob's floor distance, which no ghost agrees with: two tracks, at the people, none at the ghosts."""
    people = [(4.0, 3.0), (6.0, 5.0)]
    cams = {"a": (0.0, 0.0, math.atan2(4.0, 5.0)), "b": (10.0, 0.0, math.atan2(4.0, -5.0))}
    fusion = Fusion(ManagerConfig(manager=ManagerSection(id="m1")))
    t0 = 1_800_000_000_000_000_000
    infos = [_pinhole_info(s, x, y, yaw) for s, (x, y, yaw) in cams.items()]

    def feats(sid: str, seq: int, t_ns: int) -> Features:
        x, y, _ = cams[sid]
        blobs = [_blob(k, p, (x, y)) for k, p in enumerate(people)]
        return Features(sensor_id=sid, seq=seq, stamp_ns=t_ns, frame_index=seq, blobs=blobs)

    for n in range(12):
        t_ns = t0 + n * 250_000_000
        fusion.absorb(Batch(features=[feats(s, n + 1, t_ns) for s in cams], infos=infos if n == 0 else []))
        res = fusion.step(t_ns)
    tracks = res.trackset.tracks
    assert len(tracks) == 2
    for p in people:
        assert min(math.hypot(t.x_m - p[0], t.y_m - p[1]) for t in tracks) < 0.1


def _blob(k: int, person: tuple[float, float], cam: tuple[float, float]) -> Blob:
    d = math.hypot(person[0] - cam[0], person[1] - cam[1])
    return Blob(
        local_id=k,
        bearing_rad=math.atan2(person[1] - cam[1], person[0] - cam[0]),
        width_rad=0.45 / d,
        top_elev_rad=math.atan2(1.75 - Z_M, d),
        bottom_elev_rad=math.atan2(-Z_M, d),
        bbox_u_px=900,
        bbox_v_px=300,
        bbox_w_px=50,
        bbox_h_px=300,
    )


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
        aligned = align([("c", ing.buffers["c"], params)], (10_000 + t_ms) * ms)
        assert aligned.sensor_ids == ("c",)
        assert aligned.local_id.tolist() == [want], t_ms


def test_tracks_of_people_who_left_end_at_once_and_unknown_ids_are_bounded() -> None:
    cfg = ManagerConfig(manager=ManagerSection(id="m1"))
    fusion = Fusion(cfg)
    t0 = 1_800_000_000_000_000_000
    cams = {"a": (0.0, 0.0, math.pi / 4), "b": (10.0, 0.0, 3 * math.pi / 4), "c": (5.0, 10.0, -math.pi / 2)}
    infos = [_pinhole_info(s, x, y, yaw) for s, (x, y, yaw) in cams.items()]
    person = (5.0, 4.0)

    def feats(sid: str, seq: int, t_ns: int, present: bool) -> Features:
        x, y, _ = cams[sid]
        blobs = [_blob(1, person, (x, y))] if present else []
        return Features(sensor_id=sid, seq=seq, stamp_ns=t_ns, frame_index=seq, blobs=blobs)

    confirmed_at_leave = 0
    for n in range(30):
        t_ns = t0 + n * 250_000_000
        here = n < 20
        batch = Batch(features=[feats(s, n + 1, t_ns, here) for s in cams], infos=infos if n == 0 else [])
        fusion.absorb(batch)
        res = fusion.step(t_ns + 1)
        tracks = [tr for tr in res.trackset.tracks if tr.state != "tentative"]
        if n == 19:
            confirmed_at_leave = len(tracks)
            assert math.hypot(tracks[0].x_m - person[0], tracks[0].y_m - person[1]) < 0.1
        if n == 21:
            assert tracks == []  # three views that should see them see nobody: gone within half a second
    assert confirmed_at_leave == 1
    # Made-up sensor ids cannot grow the buffers without bound.
    fakes = [Features(sensor_id=f"fake{i:05d}", seq=1, stamp_ns=t0 + 8_000_000_000, frame_index=1) for i in range(500)]
    fusion.absorb(Batch(features=fakes))
    fusion.step(t0 + 8_000_000_001)
    assert len(fusion.sensors.buffers) <= 64
    fusion.step(t0 + 12_000_000_000)
    assert set(fusion.sensors.buffers) <= set(cams)  # stale, never announced: forgotten


@pytest.mark.parametrize("kind", ["pinhole", "ptz"])
def test_one_blank_frame_of_every_camera_does_not_end_the_tracks(kind: str) -> None:
    """A sudden light change blanks every camera for a frame: the person is still there (PTZ heads too)."""
    fusion = Fusion(ManagerConfig(manager=ManagerSection(id="m1")))
    t0 = 1_800_000_000_000_000_000
    cams = {"a": (0.0, 0.0, math.pi / 4), "b": (10.0, 0.0, 3 * math.pi / 4), "c": (5.0, 10.0, -math.pi / 2)}
    infos = [_pinhole_info(s, x, y, yaw, kind) for s, (x, y, yaw) in cams.items()]
    fusion.absorb(Batch(infos=infos))
    assert fusion.step(t0).skipped is False
    person = (5.0, 4.0)

    def feats(sid: str, seq: int, t_ns: int, blank: bool) -> Features:
        x, y, _ = cams[sid]
        blob = _blob(1, person, (x, y))
        return Features(sensor_id=sid, seq=seq, stamp_ns=t_ns, frame_index=seq, blobs=[] if blank else [blob])

    ids = []
    for n in range(1, 20):
        t_ns = t0 + n * 250_000_000
        fusion.absorb(Batch(features=[feats(s, n, t_ns, n == 10) for s in cams]))
        res = fusion.step(t_ns + 1)
        ids.append([tr.track_id for tr in res.trackset.tracks if tr.state != "tentative"])
    assert ids[8] == ids[9] == ids[10] == ids[-1] == ["m1-1"]


@pytest.mark.parametrize(("left_px", "width_px", "cut"), [(0.0, 40.0, 1.0), (900.0, 50.0, 0.0), (1880.0, 40.0, -1.0)])
def test_a_box_the_pictures_side_cuts_says_which_way_its_person_goes_on(
    left_px: float, width_px: float, cut: float
) -> None:
    """A camera at the origin looks along +x: the picture's left is the +y side (bearings grow), its right the -y
    side. A box at the left border is of a person who goes on to larger bearings, one at the right to smaller."""
    poses = {"c": PoseEstimate("c", 0.0, 0.0, Z_M, 0.0, "surveyed")}
    infos = {"c": _pinhole_info("c", 0.0, 0.0, 0.0)}
    aligned = _view_of([(6.0, 1.0)], (0.0, 0.0))
    aligned.values[:, 7], aligned.values[:, 8] = left_px, left_px + width_px
    views = build_views(aligned, poses, infos, lambda _s: 0.0035, feet=FEET)
    assert views.side_cut.tolist() == [cut]
