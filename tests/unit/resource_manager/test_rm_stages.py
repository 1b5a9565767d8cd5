"""Pair ranking, localisation, tracker, PTZ allocation, history and config of the manager (planner: own file)."""

from __future__ import annotations

import math
from pathlib import Path

import msgspec
import numpy as np
import pytest

from common.error_model import pair_position_error
from common.errors import ConfigError
from common.schema import PanoramicModel, PinholeModel, Pose, SensorInfo, Track
from resource_manager.config import load_manager_config
from resource_manager.serve.history import IdAllocator, TrackLog, TrackStore, read_segments
from resource_manager.serve.ptz import PtzAllocator, PtzTarget
from resource_manager.stereo.localize import Measurement, localize_best_pair, localize_least_squares
from resource_manager.stereo.pairs import CameraGeom, rank_pairs
from tests.support import REPO
from tests.unit.resource_manager.test_rm_match import view

SIG = math.radians(0.2)


# -- pairs and localisation ---------------------------------------------------------------------------
def test_rank_pairs_prefers_the_wide_angle_pair() -> None:
    target = np.array([3.0, 3.0])
    cams = [
        CameraGeom("near-line", np.array([0.0, 0.0]), SIG),
        CameraGeom("same-line", np.array([1.0, 1.0]), SIG),  # colinear with near-line and the target
        CameraGeom("side", np.array([6.0, 0.0]), SIG),
    ]
    ranked = rank_pairs(target, cams)
    assert len(ranked) == 3
    assert {ranked[0].a, ranked[0].b} == {"same-line", "side"} or {ranked[0].a, ranked[0].b} == {"near-line", "side"}
    assert {ranked[-1].a, ranked[-1].b} == {"near-line", "same-line"}
    assert ranked[0].error_m < ranked[-1].error_m


def test_rank_pairs_counts_mutual_calibration_baseline_error() -> None:
    target = np.array([3.0, 3.0])
    a = CameraGeom("a", np.array([0.0, 0.0]), SIG)
    b_survey = CameraGeom("b", np.array([6.0, 0.0]), SIG)
    b_mutual = CameraGeom("b", np.array([6.0, 0.0]), SIG, sigma_xy_m=0.15)
    assert rank_pairs(target, [a, b_mutual])[0].error_m > rank_pairs(target, [a, b_survey])[0].error_m


def test_localize_triangulation_covariance_matches_error_model() -> None:
    v1 = view("p1", (0.0, 0.0), [(2.0, 3.0, 1.8, 1)])
    v2 = view("p2", (5.0, 0.0), [(2.0, 3.0, 1.8, 1)])
    m = localize_best_pair(v1, 0, v2, 0, min_sigma_m=0.0)
    assert m is not None and m.method == "triangulation"
    assert np.allclose(m.xy, [2.0, 3.0], atol=1e-9)
    assert m.height_m == pytest.approx(1.8, abs=1e-6)
    predicted = pair_position_error((0, 0), (5, 0), (2, 3), SIG)
    assert math.sqrt(np.trace(m.cov)) == pytest.approx(predicted, rel=1e-6)
    assert m.predicted_error_m == pytest.approx(predicted, rel=1e-6)


def test_size_ratio_refuses_a_blob_wider_than_one_person() -> None:
    """Beyond the second camera, on the camera line, Eq. 2 ranges by the width ratio; a merged group's blob (two
    people wide) would put the fix far along the baseline: no fix from it (twice as wide still picks Eq. 2 by the
    crossover rule, far wider switches to Eq. 1 with its large covariance)."""
    v1 = view("p1", (0.0, 0.0), [(5.0, 0.02, 1.8, 1)])
    v2 = view("p2", (3.0, 0.0), [(5.0, 0.02, 1.8, 1)])
    m = localize_best_pair(v1, 0, v2, 0)
    assert m is not None and m.method == "size_ratio"
    assert math.hypot(m.xy[0] - 5.0, m.xy[1] - 0.02) < 0.1
    wide = view("p1", (0.0, 0.0), [(5.0, 0.02, 1.8, 1)])
    wide.width_rad[0] *= 2.0  # 0.9 m at 5 m: by Eq. 2 the person would stand far beyond 5 m
    assert localize_best_pair(wide, 0, v2, 0) is None


def test_localize_least_squares_all_views() -> None:
    vs = [view(f"p{k}", o, [(2.0, 3.0, 1.7, 1)]) for k, o in enumerate([(0.0, 0.0), (5.0, 0.0), (5.0, 6.0)])]
    m = localize_least_squares([(v, 0) for v in vs], {})
    assert m is not None and m.method == "least_squares" and np.allclose(m.xy, [2.0, 3.0], atol=1e-6)
    assert len(m.sensors) == 3


# -- tracker --------------------------------------------------------------------------------------
def _meas(x: float, y: float) -> Measurement:
    return Measurement(np.array([x, y]), np.eye(2) * 0.02**2, 1.7, "triangulation", ("a", "b"), 0.02, ())


# -- PTZ allocation -------------------------------------------------------------------------------
def _ptz(sid: str, x: float, y: float) -> SensorInfo:
    return SensorInfo(
        sensor_id=sid,
        seq=0,
        stamp_ns=1,
        kind="ptz",
        model=PinholeModel(width_px=640, height_px=480, k=[500.0, 0, 320, 0, 500, 240, 0, 0, 1]),
        pose=Pose(x_m=x, y_m=y, z_m=2.5, yaw_rad=0.0),
        pose_source="surveyed",
    )


def test_ptz_priority_preemption_release_and_track_end() -> None:
    alloc = PtzAllocator()
    alloc.update_info(_ptz("z1", 0.0, 0.0))
    alloc.update_info(_ptz("z2", 50.0, 0.0))  # too far from the person
    person = PtzTarget("m-1", 3.0, 4.0, 1.8)
    assert alloc.acquire("a1", person, "m-1", 1, 10) == ("z1", "")
    sid, why = alloc.acquire("a2", person, "m-1", 1, 11)
    assert sid == "" and "priority" in why  # equal priority does not preempt
    assert alloc.acquire("a3", person, "m-1", 5, 12) == ("z1", "")  # higher priority preempts
    assert alloc.ended[-1][0].agent_id == "a1" and "preempted" in alloc.ended[-1][1]
    (aim,) = alloc.tick({"m-1": person})
    assert aim.pan_rad == pytest.approx(math.atan2(4.0, 3.0))
    assert aim.tilt_rad == pytest.approx(math.atan2(1.8 * 0.85 - 2.5, 5.0))
    assert 1.0 <= aim.zoom <= 10.0
    assert alloc.release("a3", "m-1") == ("z1", "")
    assert alloc.release("a3", "m-1")[0] == ""
    assert alloc.acquire("a1", person, "m-1", 0, 13) == ("z1", "")
    assert alloc.tick({}) == [] and not alloc.assignments  # the track ended
    assert alloc.acquire("a1", None, "m-9", 0, 14)[1].startswith("no current track")


def test_ptz_none_can_see() -> None:
    alloc = PtzAllocator()
    alloc.update_info(_ptz("z2", 50.0, 0.0))
    sid, why = alloc.acquire("a1", PtzTarget("m-1", 3.0, 4.0, 1.8), "m-1", 0, 1)
    assert sid == "" and "can see" in why


# -- history --------------------------------------------------------------------------------------
def _track(tid: str, t_ns: int, x: float = 0.0) -> Track:
    return Track(
        manager_id="m",
        seq=1,
        stamp_ns=t_ns,
        track_id=tid,
        x_m=x,
        y_m=0.0,
        height_m=1.7,
        vx_mps=0.0,
        vy_mps=0.0,
        cov_xx_m2=0.01,
        cov_xy_m2=0.0,
        cov_yy_m2=0.01,
        state="confirmed",
        method="triangulation",
    )


def test_id_allocator_never_repeats_across_crashes(tmp_path: Path) -> None:
    a = IdAllocator(tmp_path, "mgr", block=4)
    ids = [a() for _ in range(6)]
    assert ids == [f"mgr-{k}" for k in range(1, 7)]
    b = IdAllocator(tmp_path, "mgr", block=4)  # "crash": no clean shutdown of a
    nxt = b()
    assert int(nxt.split("-")[1]) > 6
    (tmp_path / "next_id").write_text("garbage")
    with pytest.raises(ConfigError, match="integer"):
        IdAllocator(tmp_path, "mgr")


def test_track_log_roundtrip_torn_tail_and_store(tmp_path: Path) -> None:
    log = TrackLog(tmp_path, segment_s=1.0, retain_s=10.0)
    for k in range(30):
        log.append([_track("m-1", k * 100_000_000, x=k), _track("m-2", k * 100_000_000)], k * 100_000_000)
    log.close()
    segs = sorted(tmp_path.glob("tracks-*.log"))
    assert len(segs) == 3
    with segs[-1].open("ab") as fh:
        fh.write(b"\x50\x00\x00\x00partial")  # a record torn by a crash
    back = read_segments(tmp_path, 1_500_000_000)
    assert [t.stamp_ns for t in back] == sorted(t.stamp_ns for t in back)
    assert {t.track_id for t in back} == {"m-1", "m-2"} and len(back) == 30
    store = TrackStore(history_s=1.0, rate_hz=5.0)
    kept = [store.add(t) for t in read_segments(tmp_path, 0) if t.track_id == "m-1"]
    assert sum(kept) == 15  # 10 Hz in, 5 Hz kept
    assert store.latest("m-1") is not None and store.latest("m-1").x_m == 28.0  # type: ignore[union-attr]
    assert [t.x_m for t in store.path("m-1", 2_500_000_000)] == [26.0, 28.0]
    store.prune(3_000_000_000)
    assert all(t.stamp_ns >= 2_000_000_000 for t in store.path("m-1", 0))


# -- config ---------------------------------------------------------------------------------------
def test_example_config_loads() -> None:
    cfg = load_manager_config(REPO / "deploy/nodes/examples/manager.toml")
    assert cfg.manager.id == "mgr1" and cfg.manager.matcher == "greedy" and cfg.keys.root == "pano/@v1"
    assert Path(cfg.manager.state_dir).is_absolute()


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ('[manager]\nid = "m1"\nmatcher = "best"\n', "matcher"),
        ('[manager]\nid = "M 1"\n', "manager.id"),
        ('[manager]\nid = "m1"\nbogus = 1\n', "unknown key 'manager.bogus'"),
        ('[manager]\nid = "m1"\n[planner]\nroom = [0, 0, -1, 5]\n', "planner.room"),
        (
            '[manager]\nid = "m1"\n' + '[[pose]]\nid = "a"\nx_m = 0\ny_m = 0\nz_m = 1\n' * 2,
            "unique",
        ),
        ("[zenoh]\n", "missing required key 'manager'"),
        ('[manager]\nid = "m1"\nrate_hz = 0\n', "rate_hz"),
    ],
)
def test_bad_configs(tmp_path: Path, text: str, message: str) -> None:
    p = tmp_path / "m.toml"
    p.write_text(text)
    with pytest.raises(ConfigError, match=message):
        load_manager_config(p)


def test_config_is_frozen() -> None:
    cfg = load_manager_config(REPO / "deploy/nodes/examples/manager.toml")
    with pytest.raises(AttributeError):
        cfg.manager.id = "x"  # type: ignore[misc]
    assert msgspec.structs.replace(cfg.manager, rate_hz=5.0).rate_hz == 5.0


def test_known_bodies_are_not_people() -> None:
    from resource_manager.ingest.align import AlignedBlob, AlignedView
    from resource_manager.poses.solver import PoseEstimate
    from resource_manager.views.build import build_views

    def b(lid: int, bearing: float, width: float) -> AlignedBlob:
        return AlignedBlob(lid, bearing, width, 0.0 if lid == 1 else 0.15, -0.3, [], True)

    poses = {
        "p1": PoseEstimate("p1", 0.0, 0.0, 1.1, 0.0, "surveyed"),
        "r1": PoseEstimate("r1", 3.0, 0.0, 1.1, 0.0, "mutual"),
    }
    # p1 sees r1's body (R = 0.18 m at 3 m: 0.12 rad wide, top at the camera) straight ahead, a person at
    # 0.5 rad, people merged in front of it (wide), and a person right behind it (taller top)
    blobs = [b(1, 0.002, 0.12), b(2, 0.5, 0.1), b(3, 0.01, 0.8), b(4, 0.003, 0.1)]
    av = AlignedView("p1", 1, blobs, [], "interpolated")
    model = PanoramicModel(width_px=1080, height_px=162, f_v_px=256.0, v0_px=93.0)
    robot = SensorInfo(sensor_id="r1", seq=0, stamp_ns=1, kind="panoramic", model=model, body_radius_m=0.18)
    views = build_views({"p1": av}, poses, {"r1": robot}, lambda s: SIG)
    assert list(views["p1"].local_id) == [2, 3, 4]  # only the body is gone
    bodiless = msgspec.structs.replace(robot, body_radius_m=0.0)
    assert list(build_views({"p1": av}, poses, {"r1": bodiless}, lambda s: SIG)["p1"].local_id) == [1, 2, 3, 4]


def test_pinhole_field_of_view() -> None:
    from resource_manager.views.blobs import ViewBlobs
    from resource_manager.views.build import pinhole_fov

    # camera looking along world +y, level: R rows are the camera axes in world coordinates
    model = PinholeModel(
        width_px=640, height_px=480, k=[320.0, 0, 320, 0, 320, 240, 0, 0, 1], r=[1.0, 0, 0, 0, 0, -1, 0, 1, 0]
    )
    fov = pinhole_fov(model, margin_rad=0.0)
    assert fov is not None
    assert fov[0] == pytest.approx(math.pi / 2) and fov[1] == pytest.approx(math.pi / 4)
    v = ViewBlobs(
        "c", np.zeros(2), 1.0, SIG, np.zeros(0), np.zeros(0), np.zeros(0), None, np.zeros(0, np.int64), fov=fov
    )
    assert v.sees(math.pi / 2 + 0.7) and not v.sees(0.0)
    down = PinholeModel(width_px=640, height_px=480, k=[320.0, 0, 320, 0, 320, 240, 0, 0, 1])  # R = I: looks down z
    assert pinhole_fov(down) is None
