"""The manager's gate (who it fuses, identity, clock), its SensorInfo gate, and PTZ holds as leases."""

from __future__ import annotations

import msgspec
import pytest

from common.schema import Features, Pose, PtzRequest, PtzState
from resource_manager.config import ManagerConfig, ManagerSection
from resource_manager.fusion import Batch, Fusion
from resource_manager.ingest.gate import RefusalCounter, SenderGate, sender_in_key
from resource_manager.ingest.infos import InfoGate
from resource_manager.serve.ptz import PtzAllocator, PtzAsk, PtzParams, PtzTarget
from tests.unit.resource_manager.synth import Cam, info_for

NOW = 1_800_000_000_000_000_000
SKEW = 5_000_000_000
LEAD = 250_000_000


def feat(sid: str, stamp_ns: int = NOW) -> Features:
    return Features(sensor_id=sid, seq=1, stamp_ns=stamp_ns, frame_index=1)


@pytest.mark.parametrize(
    ("key", "sid"),
    [
        ("pano/@v1/sensor/pano1/features", "pano1"),
        ("pano/@v1/sensor/pano1/ptz/state", "pano1"),
        ("pano/@v1/sensor/x", "x"),
        ("pano/@v1/tracks", ""),
        ("other/@v1/sensor/pano1/features", ""),
    ],
)
def test_sender_in_key(key: str, sid: str) -> None:
    assert sender_in_key(key, "pano/@v1/sensor/") == sid


def test_gate_lists_refuses_and_counts_by_reason() -> None:
    gate = SenderGate.of(["pano1", "pano2"], SKEW, LEAD)
    assert gate.allows("pano1") and not gate.allows("evil") and gate.expected == ["pano1", "pano2"]
    gate.refuse_unlisted("evil", 40)
    assert gate.features("pano1", feat("pano1"), NOW)
    assert not gate.features("pano2", feat("pano1"), NOW)  # pano1's frame on pano2's key
    for stamp in (0, 2**63 - 1, NOW + LEAD + 1, NOW - SKEW - 1):  # 1970, 2262, just ahead, just too old
        assert not gate.features("pano1", feat("pano1", stamp), NOW)
    assert gate.features("pano1", feat("pano1", NOW - SKEW), NOW)
    assert gate.features("pano1", feat("pano1", NOW + LEAD), NOW)
    state = PtzState(sensor_id="pano1", seq=0, stamp_ns=0, pan_rad=0.0, tilt_rad=0.0, zoom=1.0)
    assert gate.same_sender("pano1", state) and not gate.same_sender("pano2", state)
    assert gate.same_agent("a1", "a1") and not gate.same_agent("a2", "a1")
    top = {r.sender_id: (r.unlisted, r.wrong_id, r.skewed, r.ahead) for r in gate.refusals.top(10)}
    # 1970 and just too old are late (skewed); 2262 and just ahead are stamped in the future (ahead).
    assert top == {"evil": (40, 0, 0, 0), "pano2": (0, 2, 0, 0), "pano1": (0, 0, 2, 2), "a2": (0, 1, 0, 0)}
    assert gate.refusals.total == 47
    assert [r.sender_id for r in gate.refusals.top(1)] == ["evil"]


def test_any_sensor_is_explicit() -> None:
    gate = SenderGate.of(["*"], SKEW)
    assert gate.any_sensor and gate.allows("whoever") and gate.expected == []


def test_refusal_counter_is_bounded_but_always_counts_the_listed_sensors() -> None:
    c = RefusalCounter(max_senders=3, reserved=frozenset({"pano1"}))
    for i in range(1000):
        c.add(f"fresh{i}", "unlisted")
    c.add("NOT_AN_ID", "unlisted")
    c.add("pano1", "skewed", 7)  # after the flood of fresh ids filled every slot
    assert len(c.counts) == 4 and c.others == 998 and c.total == 1008
    assert c.top(1)[0].sender_id == "pano1" and c.top(1)[0].skewed == 7


def _pose(info: object, x: float) -> object:
    return msgspec.structs.replace(info, pose=Pose(x_m=x, y_m=5.1, z_m=1.2, yaw_rad=1.57))


def test_a_put_never_moves_a_held_sensor_info_only_a_read_does() -> None:
    real = _pose(info_for(Cam("pano3", 4.2, 5.1)), 4.2)
    forged = _pose(real, 0.5)
    g = InfoGate(refresh_ns=2_000_000_000)
    assert g.offer_put(real) == real  # the first one is taken at once, and read to confirm
    assert g.due(0, {"pano3"}) == ["pano3"]
    assert g.offer_read(real, 1) is None  # the sensor says the same: nothing to apply
    for _ in range(100):  # forged puts: never taken, each only a reason to read again
        assert g.offer_put(forged) is None
    assert g.ignored_puts == 100
    assert g.due(100_000_000, {"pano3"}) == []  # not more often than min_gap
    assert g.due(300_000_000, {"pano3"}) == ["pano3"]
    assert g.offer_read(real, 300_000_000) is None
    assert g.held["pano3"] == real
    # A re-stamped copy of what is held is no change; the sensor's own changed answer is taken.
    assert g.offer_put(msgspec.structs.replace(real, seq=9, stamp_ns=99)) is None and g.ignored_puts == 100
    moved = _pose(real, 4.3)
    assert g.offer_read(moved, 400_000_000) == moved
    # Periodic re-reads, and one as soon as a sensor's liveliness token comes back.
    assert g.due(2_400_000_000, {"pano3", "pano9"}) == ["pano3", "pano9"]
    g.came_back("pano3")
    assert g.due(2_700_000_000, {"pano3", "pano9"}) == ["pano3"]


def test_a_forged_first_info_is_replaced_by_the_first_read() -> None:
    real = _pose(info_for(Cam("pano3", 4.2, 5.1)), 4.2)
    g = InfoGate(refresh_ns=2_000_000_000)
    assert g.offer_put(_pose(real, 0.5)) is not None  # an impostor was first
    assert g.due(0, {"pano3"}) == ["pano3"]
    assert g.offer_read(real, 1) == real


def test_fusion_keeps_a_static_pose_whatever_the_info_stamp() -> None:
    """A forged SensorInfo stamped in 2262 must not shadow the real ones that follow."""
    cfg = ManagerConfig(manager=ManagerSection(id="m1", sensors=["pano3"]))
    f = Fusion(cfg)
    real = info_for(Cam("pano3", 4.2, 5.1))
    f.absorb(Batch(infos=[msgspec.structs.replace(_pose(real, 0.5), stamp_ns=2**63 - 1)]))
    f.absorb(Batch(infos=[real]))
    assert f.poses.surveyed()["pano3"].x_m == pytest.approx(4.2)


# -- PTZ leases ---------------------------------------------------------------


def _alloc(lease_s: float = 10.0) -> PtzAllocator:
    z1 = msgspec.structs.replace(
        info_for(Cam("z1", 0.0, 0.0)), kind="ptz", pose=Pose(x_m=0.0, y_m=0.0, z_m=2.5, yaw_rad=0.0)
    )
    return PtzAllocator(PtzParams(lease_s=lease_s), infos={"z1": z1})


PERSON = PtzTarget("m-1", 3.0, 4.0, 1.8)


def ask(agent: str, action: str = "acquire", t_ns: int = 0, lease_s: float = 0.0, prio: int = 0) -> PtzAsk:
    req = PtzRequest(agent_id=agent, seq=1, stamp_ns=0, action=action, track_id="m-1", priority=prio, lease_s=lease_s)  # type: ignore[arg-type]
    return PtzAsk(req, agent, t_ns, 1)


def test_a_hold_expires_unless_renewed() -> None:
    a = _alloc(lease_s=10.0)
    ans = a.answer(ask("a1", t_ns=0), PERSON)
    assert ans.sensor_id == "z1" and ans.lease_s == 10.0
    assert a.tick({"m-1": PERSON}, 9_000_000_000)  # still aimed
    assert a.answer(ask("a1", t_ns=9_000_000_000), PERSON).sensor_id == "z1"  # renewed
    assert a.tick({"m-1": PERSON}, 18_000_000_000)
    assert a.tick({"m-1": PERSON}, 19_000_000_000) == []  # 10 s after the renewal: gone
    assert [why for _, why in a.ended] == ["lease expired (not renewed)"]
    assert a.answer(ask("a2", t_ns=19_500_000_000), PERSON).sensor_id == "z1"


def test_a_request_may_ask_for_less_never_more() -> None:
    a = _alloc(lease_s=10.0)
    assert a.answer(ask("a1", lease_s=3.0), PERSON).lease_s == 3.0
    assert a.answer(ask("a1", lease_s=3600.0), PERSON).lease_s == 10.0


def test_a_hold_ends_when_its_agent_goes_and_another_gets_the_camera() -> None:
    cfg = ManagerConfig(manager=ManagerSection(id="m1", sensors=["z1"]))
    f = Fusion(cfg)
    f.ptz = _alloc()
    f.ptz_targets = lambda: {"m-1": PERSON}  # type: ignore[method-assign]
    (first,) = f.absorb(Batch(ptz_requests=[ask("a1")])).ptz_answers
    assert first.sensor_id == "z1"
    (second,) = f.absorb(Batch(ptz_requests=[ask("a2", prio=0)])).ptz_answers
    assert second.sensor_id == "" and "held" in second.reason
    assert "a1" not in second.reason  # who holds it is not the asker's business
    third = f.absorb(Batch(agents={"a1": False}, ptz_requests=[ask("a2")]))  # a1 exited; a2 asks in the same tick
    assert third.ptz_answers[0].sensor_id == "z1"
    assert any("agent left" in why for _, why in third.ptz_ended)


def test_release_is_the_holders_own() -> None:
    a = _alloc()
    a.answer(ask("a1"), PERSON)
    assert a.answer(ask("a2", action="release"), PERSON).sensor_id == ""
    assert "z1" in a.assignments
    assert a.answer(ask("a1", action="release"), PERSON).sensor_id == "z1"
    assert not a.assignments
