"""Poses: surveyed, overrides, mutual calibration chained from known cameras, unknown stays unknown."""

from __future__ import annotations

import math

import numpy as np
import pytest

from resource_manager.ingest.align import AlignedSighting
from resource_manager.poses.solver import MutualParams, PoseEstimate, PoseSolver
from resource_manager.views.settling import SettleParams, ViewTrust
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
    s = PoseSolver(MutualParams(**params))  # type: ignore[arg-type]
    for c in cams:
        s.update_info(info_for(c))
    return s


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


# -- settling: a robot's views after it moved (resource_manager/settling.py) ------------------------------------
def _pose(sid: str, x: float, y: float, sigma: float = 0.01, yaw: float = 0.0) -> PoseEstimate:
    return PoseEstimate(sid, x, y, 1.1, yaw, "mutual", sigma, math.radians(0.3))


def test_views_of_a_robot_that_moved_wait_for_its_stop_relearnt_background_and_converged_pose() -> None:
    # An older node (no Features.state): it goes blank while it drives and relearns; blobs again say it sees.
    trust = ViewTrust(SettleParams(still_ns=500 * MS, relearn_max_ns=4000 * MS))
    tick = 100 * MS
    out = {}
    for k in range(80):  # 8 s at 10 Hz: parked, sent at 1 s, drives 1 -> 3 s, stops; blobs again from 4.2 s
        t = k * tick
        x = 1.0 if t < 1000 * MS else min(1.0 + 0.5 * (t - 1000 * MS) / 1e9, 2.0)
        blobs = ["r1"] if t < 1000 * MS or t >= 4200 * MS else []
        en_route = ["r1"] if 1000 * MS <= t < 3000 * MS else []
        out[t] = trust.update(t, {"r1": _pose("r1", x, 0.0)}, mobile=["r1"], en_route=en_route, with_blobs=blobs)
    assert all(not out[k * tick] for k in range(10))  # parked: trusted from its first pose
    assert all(out[k * tick] == {"r1"} for k in range(10, 42))  # driving, then stopped but relearning (no blobs)
    assert all(not out[k * tick] for k in range(42, 80))  # blobs again after the stop: trusted at once


def test_a_stopped_robot_nobody_in_view_of_is_trusted_after_relearn_max() -> None:
    trust = ViewTrust(SettleParams(still_ns=500 * MS, relearn_max_ns=2000 * MS))
    seen = []
    for k in range(60):
        t = k * 100 * MS
        x = 1.0 + 0.05 * min(k, 20)  # moved by someone else (no goal): 1 m in 2 s, then still
        if not trust.update(t, {"r1": _pose("r1", x, 0.0)}, mobile=["r1"], en_route=[], with_blobs=[]):
            seen.append(k)
    stop_k = 20
    assert seen[:5] == list(range(5))  # before it had moved move_m
    first = next(k for k in seen if k > 5)
    # still from 2.0 s: the 0.5 s window is met at 2.5 s, the views trusted relearn_max (2 s) after the stop
    assert first == stop_k + 20 and seen[-1] == 59


def test_pose_noise_of_a_parked_robot_drops_nothing_and_a_loose_pose_keeps_a_moved_one_out() -> None:
    rng = np.random.default_rng(3)
    trust = ViewTrust(SettleParams())
    for k in range(50):
        p = _pose("r1", 2.0 + rng.normal(0, 0.03), 1.0 + rng.normal(0, 0.03), yaw=rng.normal(0, 0.02))
        assert not trust.update(k * 100 * MS, {"r1": p}, mobile=["r1"], en_route=[], with_blobs=["r1"])
    trust = ViewTrust(SettleParams(max_sigma_xy_m=0.05))
    for k in range(50):
        x = 2.0 if k < 10 else 3.0  # jumped 1 m: moved
        out = trust.update(
            k * 100 * MS, {"r1": _pose("r1", x, 1.0, sigma=0.2)}, mobile=["r1"], en_route=[], with_blobs=["r1"]
        )
        assert out == (frozenset() if k < 10 else {"r1"})  # its pose is still 0.2 m loose: not settled
    assert not trust.update(50 * 100 * MS, {"r1": _pose("r1", 3.0, 1.0)}, mobile=["r1"], en_route=[], with_blobs=["r1"])


def test_a_node_that_says_it_cannot_see_is_left_out_and_a_robot_back_when_relearnt_and_still() -> None:
    trust = ViewTrust(SettleParams(still_ns=500 * MS))
    poses = {"p1": PoseEstimate("p1", 0.0, 0.0, 1.1, 0.0, "surveyed"), "r1": _pose("r1", 1.0, 0.0)}
    # A static camera learning its background (start, light change): no views from it, whatever its blobs.
    out = trust.update(0, poses, mobile=["r1"], en_route=[], with_blobs=["p1", "r1"], states={"p1": "learning"})
    assert out == {"p1"}
    seen = {}
    for k in range(1, 70):  # the robot's node: moving 1 -> 3 s, learning 3 -> 4 s, then ok; blobs all along
        t = k * 100 * MS
        x = min(1.0 + 0.5 * max(t - 1000 * MS, 0) / 1e9, 2.0)
        state = "moving" if 1000 * MS <= t < 3000 * MS else "learning" if t < 4000 * MS and t >= 3000 * MS else "ok"
        poses["r1"] = _pose("r1", x, 0.0, sigma=0.2 if t < 5000 * MS else 0.01)  # pose loose until 5 s
        seen[k] = trust.update(
            t, poses, mobile=["r1"], en_route=[], with_blobs=["p1", "r1"], states={"r1": state} if state != "ok" else {}
        )
    assert all(not seen[k] for k in range(1, 10))
    assert all(seen[k] == {"r1"} for k in range(10, 50))  # moving, learning, then its pose still loose
    assert all(not seen[k] for k in range(50, 70))  # relearnt, still, converged


def test_a_node_that_reports_its_state_is_not_judged_moved_by_a_pose_jump() -> None:
    # A robot that stands still while its mutual-calibration pose jumps 0.45 m for 1 s (a band half hidden):
    # its node says "ok" all along (it said "learning" while warming up), so its views stay in use; the same
    # jump from a node that never reports a state is taken as a move.
    for reports, expect_dropped in ((True, False), (False, True)):
        trust = ViewTrust(SettleParams())
        dropped = []
        for k in range(60):
            t = k * 100 * MS
            x = 2.45 if 30 <= k < 40 else 2.0
            state = "learning" if (reports and k < 5) else "ok"
            out = trust.update(
                t, {"r1": _pose("r1", x, 1.0)}, mobile=["r1"], en_route=[], with_blobs=["r1"], states={"r1": state}
            )
            if k >= 5 and out:
                dropped.append(k)
        assert bool(dropped) == expect_dropped, dropped
