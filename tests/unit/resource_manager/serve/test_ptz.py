"""PTZ allocation: priority, preemption, release, aiming and the end of a track."""

from __future__ import annotations

import math

import pytest

from common.schema import PinholeModel, Pose, PtzRequest, SensorInfo
from resource_manager.serve.ptz import PtzAllocator, PtzAsk, PtzParams, PtzTarget


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
    alloc = PtzAllocator(infos={"z1": _ptz("z1", 0.0, 0.0), "z2": _ptz("z2", 50.0, 0.0)})  # z2: too far
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
    alloc = PtzAllocator(infos={"z2": _ptz("z2", 50.0, 0.0)})
    sid, why = alloc.acquire("a1", PtzTarget("m-1", 3.0, 4.0, 1.8), "m-1", 0, 1)
    assert sid == "" and "can see" in why


def _ask(agent: str, priority: int, token: int) -> PtzAsk:
    req = PtzRequest(agent_id=agent, seq=token, stamp_ns=1, action="acquire", track_id="m-1", priority=priority)
    return PtzAsk(req, agent, 10 + token, token)


def test_a_request_above_its_agents_cap_is_clipped_and_the_refusal_names_no_holder() -> None:
    params = PtzParams(max_priority={"ops": 10}, default_max_priority=1)
    alloc = PtzAllocator(params, infos={"z1": _ptz("z1", 0.0, 0.0)})
    person = PtzTarget("m-1", 3.0, 4.0, 1.8)
    first = alloc.answer(_ask("a1", 1, 1), person)
    assert first.sensor_id == "z1" and first.reason == ""
    # a2 asks 999 but its identity is capped at 1: equal to a1's hold, so no preemption, and it is told why.
    second = alloc.answer(_ask("a2", 999, 2), person)
    assert second.sensor_id == ""
    assert "clipped to 1" in second.reason and "a1" not in second.reason and "999" in second.reason
    # ops is capped at 10: it asks 50, gets 10, and that beats a1's 1.
    third = alloc.answer(_ask("ops", 50, 3), person)
    assert third.sensor_id == "z1" and "clipped to 10" in third.reason
    assert alloc.assignments["z1"].priority == 10
    assert alloc.ended[-1][0].agent_id == "a1"
