"""Poses: surveyed, overrides, mutual calibration chained from known cameras, unknown stays unknown."""

from __future__ import annotations

import math

import numpy as np
import pytest

from resource_manager.ingest.align import AlignedSighting
from resource_manager.poses.solver import MutualParams, PoseEstimate, PoseSolver
from tests.unit.resource_manager.synth import Cam, features_for, info_for

PX = math.radians(0.2)
MS = 1_000_000


def sightings(cams: list[Cam], rng: np.random.Generator, noise: float) -> dict[str, list[AlignedSighting]]:
    out = {}
    for c in cams:
        f = features_for(c, [], cams, 1, 0, rng, boundary_noise_rad=noise)
        out[c.id] = [AlignedSighting(s.target_id, s.left_rad, s.right_rad, s.body_radius_m) for s in f.sightings]
    return out


def solver(cams: list[Cam], **params: object) -> PoseSolver:
    return PoseSolver(MutualParams(**params), infos={c.id: info_for(c) for c in cams})  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("cams", "known", "unknown"),
    [
        # a surveyed camera sights the robot (range + bearing); the robot sights it back (yaw)
        ([Cam("p1", 0, 0), Cam("r1", 3, 1, yaw=2.0, mobile=True, surveyed=False)], ["p1", "r1"], []),
        # chained: p1 -> r1 -> r2 (p1 sees only r1, within its 4 m range; r2 is located through r1)
        (
            [
                Cam("p1", 0, 0, max_range_m=4.0),
                Cam("r1", 3, 0, yaw=1.0, mobile=True, surveyed=False),
                Cam("r2", 5, 3, yaw=-2.0, mobile=True, surveyed=False),
            ],
            ["p1", "r1", "r2"],
            [],
        ),
        # two robots that see only each other: no anchor, no pose
        (
            [
                Cam("p1", 0, 0, radius=0.0, sights=False),
                Cam("r1", 3, 0, mobile=True, surveyed=False),
                Cam("r2", 5, 3, mobile=True, surveyed=False),
            ],
            ["p1"],
            ["r1", "r2"],
        ),
        # resection: the robot sees two surveyed bodies that do not report sightings
        (
            [
                Cam("p1", 0, 0, sights=False),
                Cam("p2", 4, 0, sights=False),
                Cam("r1", 2, 3, yaw=0.5, mobile=True, surveyed=False),
            ],
            ["p1", "p2", "r1"],
            [],
        ),
    ],
)
def test_pose_chaining(cams: list[Cam], known: list[str], unknown: list[str]) -> None:
    s = solver(cams)
    poses = s.solve(sightings(cams, np.random.default_rng(0), 0.0), 1)
    assert sorted(poses) == known
    for c in cams:
        if c.id in poses:
            p = poses[c.id]
            assert math.hypot(p.x_m - c.x, p.y_m - c.y) < 1e-6
            assert abs(math.remainder(p.yaw_rad - c.yaw, 2 * math.pi)) < 1e-6
        else:
            assert c.id in unknown


def test_override_wins_and_unknown_source_ignored() -> None:
    cams = [Cam("p1", 0, 0), Cam("p2", 4, 0, surveyed=False)]
    s = solver(cams)
    s.overrides["p1"] = PoseEstimate("p1", 1.0, 2.0, 1.5, 0.3, "surveyed")
    poses = s.solve({}, 1)
    assert poses["p1"].x_m == 1.0 and poses["p1"].yaw_rad == 0.3
    assert "p2" not in poses  # not mobile, not surveyed, not sighted: unknown


def test_smoothing_shrinks_noise_and_reports_sigma() -> None:
    cams = [Cam("p1", 0, 0), Cam("r1", 4, 0.5, yaw=1.0, mobile=True, surveyed=False)]
    s = solver(cams, smoothing_s=1.0)
    rng = np.random.default_rng(1)
    raw_err, smooth_err = [], []
    for k in range(100):
        sg = sightings(cams, rng, PX)
        raw = s.solve_raw(sg, s.surveyed())["r1"]
        p = s.solve(sg, 1 + k * 100_000_000)["r1"]
        if k >= 30:
            raw_err.append(math.hypot(raw.x_m - 4, raw.y_m - 0.5))
            smooth_err.append(math.hypot(p.x_m - 4, p.y_m - 0.5))
    assert np.mean(smooth_err) < 0.5 * np.mean(raw_err)
    # error model: sigma_B ~ B^2 sigma_alpha / (2R) for one view, averaged over two views
    b = math.hypot(4, 0.5)
    expected_raw = b * b * math.sqrt(2) * PX / (2 * 0.18) / math.sqrt(2)
    assert raw.sigma_xy_m == pytest.approx(expected_raw, rel=0.5)
    assert 0 < p.sigma_xy_m < raw.sigma_xy_m


def test_pose_expires_without_sightings() -> None:
    cams = [Cam("p1", 0, 0), Cam("r1", 3, 0, mobile=True, surveyed=False)]
    s = solver(cams, timeout_s=1.0, hold=False)
    assert "r1" in s.solve(sightings(cams, np.random.default_rng(0), 0.0), 1)
    assert "r1" not in s.solve({}, 1 + 500_000_000)  # not re-solved at this instant: not claimed as known
    assert "r1" not in s.filters or s.solve({}, 1 + 2_000_000_000) is not None
    s.solve({}, 1 + 2_000_000_000)
    assert "r1" not in s.filters


def test_pose_is_held_between_sightings_until_the_timeout() -> None:
    cams = [Cam("p1", 0, 0), Cam("r1", 3, 0, mobile=True, surveyed=False)]
    s = solver(cams, timeout_s=1.0)
    seen = s.solve(sightings(cams, np.random.default_rng(0), 0.0), 1)["r1"]
    held = s.solve({}, 1 + 500_000_000).get("r1")  # a person walks between the robots: the pose is kept
    assert held is not None
    assert math.hypot(held.x_m - 3, held.y_m) < 0.05
    assert held.sigma_xy_m > seen.sigma_xy_m  # ...less sure of it
    assert "r1" not in s.solve({}, 1 + 2_000_000_000)  # past the timeout: unknown again
    assert "r1" not in s.filters


def test_a_lone_outlier_pose_is_refused_a_persistent_one_followed() -> None:
    cams = [Cam("p1", 0, 0), Cam("r1", 3, 0, mobile=True, surveyed=False)]
    s = solver(cams, outlier_run=3)
    rng = np.random.default_rng(1)
    for k in range(10):
        p = s.solve(sightings(cams, rng, PX), 1 + k * 100_000_000)["r1"]
    moved = [Cam("p1", 0, 0), Cam("r1", 3.6, 0, mobile=True, surveyed=False)]
    p = s.solve(sightings(moved, rng, PX), 1 + 10 * 100_000_000)["r1"]
    assert math.hypot(p.x_m - 3, p.y_m) < 0.05  # one raw pose 0.6 m off: refused
    for k in range(11, 16):
        p = s.solve(sightings(moved, rng, PX), 1 + k * 100_000_000)["r1"]
    assert math.hypot(p.x_m - 3.6, p.y_m) < 0.3  # it persists: the robot really moved (raw sigma ~0.13 m here)


def test_forged_sightings_that_agree_with_nothing_neither_move_nor_drop_a_pose() -> None:
    """A flood of sightings forged under the robots' ids (random boundaries, 8 s, longer than the timeout): every
    raw pose they give is refused (none agree with each other) and the pose is held, not lost; when they stop, the
    real sightings carry on the same filter (no restart, so no settling as if the robot had moved)."""
    cams = [Cam("p1", 0, 0), Cam("r1", 3, 0, mobile=True, surveyed=False)]
    s = solver(cams, timeout_s=2.0)
    rng = np.random.default_rng(4)
    t = 1
    for _ in range(20):
        p = s.solve(sightings(cams, rng, PX), t)["r1"]
        t += 100_000_000
    kept = s.filters["r1"]
    forged_rng = np.random.default_rng(5)
    for _ in range(80):  # 8 s of forged frames only

        def forged() -> list[AlignedSighting]:
            left = float(forged_rng.uniform(-math.pi, math.pi))
            return [AlignedSighting("r1" if forged_rng.random() < 0.5 else "p1", left,
                                    left - float(forged_rng.uniform(0.01, 0.5)), 0.18)]  # fmt: skip

        held = s.solve({"p1": forged(), "r1": forged()}, t)
        t += 100_000_000
        # Held (a forged pose that happens to lie within its tolerance nudges it: a few cm, no jump).
        assert "r1" in held and math.hypot(held["r1"].x_m - 3, held["r1"].y_m) < 0.25, held.get("r1")
    assert s.filters["r1"] is kept  # never restarted at a forged pose, never timed out
    for _ in range(10):
        p = s.solve(sightings(cams, rng, PX), t)["r1"]
        t += 100_000_000
    assert s.filters["r1"] is kept and kept.outliers == 0  # the same filter, carried on by the real sightings
    assert math.hypot(p.x_m - 3, p.y_m) < 0.05


def _settled(cams: list[Cam], rng: np.random.Generator, **params: object) -> tuple[PoseSolver, int]:
    """A solver that has watched ``cams`` for 4 s at 10 Hz (past ``settle_s``): their poses are fixed."""
    s = solver(cams, **params)
    t = 1
    for _ in range(40):
        s.solve(sightings(cams, rng, PX), t)
        t += 100 * MS
    s.take_refused()
    return s, t


@pytest.mark.parametrize(("moving", "moves"), [((), False), (("r1",), True)])
def test_one_witness_cannot_move_a_still_camera_however_long_it_insists(moving: tuple[str, ...], moves: bool) -> None:
    """p1 is r1's only witness. Its certificate stolen, it says for 10 s, consistently, that r1 stands 0.6 m away
    (the real p1 stopped): r1's node reports no motion, so its fixed pose holds and p1's sightings are refused and
    counted. Had r1's own node reported motion (it drove), the same sightings would move it there."""
    cams = [Cam("p1", 0, 0), Cam("r1", 3, 0, yaw=1.0, mobile=True, surveyed=False)]
    rng = np.random.default_rng(2)
    s, t = _settled(cams, rng)
    forged_world = [Cam("p1", 0, 0), Cam("r1", 3.0, 0.6, yaw=1.0, mobile=True, surveyed=False)]
    for _ in range(100):
        seen = sightings(forged_world, rng, PX)
        forged = {"p1": seen["p1"], "r1": sightings(cams, rng, PX)["r1"]}  # r1's own node is honest
        p = s.solve(forged, t, moving=moving)["r1"]
        t += 100 * MS
    if moves:
        assert math.hypot(p.x_m - 3.0, p.y_m - 0.6) < 0.3, p
    else:
        assert math.hypot(p.x_m - 3.0, p.y_m) < 0.05, p
        assert abs(math.remainder(p.yaw_rad - 1.0, 2 * math.pi)) < 0.01, p
        assert s.take_refused().get("p1", 0) >= 90  # every forged instant counted against its sender
    assert "r1" in s.solve(sightings(cams, rng, PX), t)  # held throughout, never lost


def test_a_witness_that_disagrees_with_the_others_is_refused_and_counted_at_once() -> None:
    """Three cameras of known pose sight r1; one lies from the first instant: its sighting is refused (counted
    against it) and r1 is placed by the other two."""
    cams = [Cam("p1", 0, 0), Cam("p2", 6, 0), Cam("p3", 3, 5), Cam("r1", 3, 1, mobile=True, surveyed=False)]
    liar_world = [Cam("p2", 6, 0), Cam("r1", 3.5, 1.8, mobile=True, surveyed=False)]
    s = solver(cams)
    rng = np.random.default_rng(3)
    for k in range(5):
        sg = sightings(cams, rng, PX)
        sg["p2"] = sightings(liar_world, rng, PX)["p2"]
        p = s.solve(sg, 1 + k * 100 * MS)["r1"]
        assert math.hypot(p.x_m - 3, p.y_m - 1) < 0.1, p
    assert s.take_refused() == {"p2": 5}


def test_a_static_camera_placed_by_sightings_never_moves_even_if_its_node_says_it_moves() -> None:
    cams = [Cam("p1", 0, 0), Cam("s1", 3, 0, mobile=False, surveyed=False)]
    rng = np.random.default_rng(4)
    s, t = _settled(cams, rng)
    away = [Cam("p1", 0, 0), Cam("s1", 3.0, 0.8, mobile=False, surveyed=False)]
    for _ in range(30):
        p = s.solve(sightings(away, rng, PX), t, moving=("s1",))["s1"]
        t += 100 * MS
    assert math.hypot(p.x_m - 3.0, p.y_m) < 0.05, p


def test_a_settled_pose_outlives_a_pause_in_its_sightings_until_its_node_reports_motion() -> None:
    """Still robots whose sightings pause (people in front of the bands, a loaded host) keep their fixed pose;
    once the robot's node reports motion and nothing places it, the pose times out as a moving one does."""
    cams = [Cam("p1", 0, 0), Cam("r1", 3, 0, mobile=True, surveyed=False)]
    s, t = _settled(cams, np.random.default_rng(5), timeout_s=2.0)
    held = s.solve({}, t + 5_000 * MS)["r1"]  # 5 s without a sighting
    assert math.hypot(held.x_m - 3, held.y_m) < 0.05
    s.solve({}, t + 5_100 * MS, moving=("r1",))
    assert "r1" not in s.solve({}, t + 7_200 * MS, moving=("r1",))
