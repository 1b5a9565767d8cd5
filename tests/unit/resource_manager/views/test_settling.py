"""Settling: a robot's views left out while it moves, its node cannot see or its pose has not re-converged."""

from __future__ import annotations

import math

import numpy as np

from resource_manager.poses.solver import PoseEstimate
from resource_manager.views.settling import SettleParams, ViewTrust

MS = 1_000_000


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
