"""Hostile input (issue 8): 10^5 random and mutated payloads on every key the manager and the
nodes subscribe to, as fast as possible; oversize payloads; a flood of made-up sensors.

Expected: no process crashes; every bad payload is counted in the receiver's status (decode
errors, or dropped when its inbox was full); the manager keeps tracking the real data (real
detection nodes of a simulated room); memory stays bounded.

Every hostile payload is checked here to fail ``common.codec.decode`` for the type the key
carries, so "counted" can be checked exactly: on the keys of the sensors the manager fuses, its
``decode_errors + dropped_msgs`` must grow by at least the number sent (more only by real frames
dropped meanwhile). Payloads under ids it does not fuse are refused by key, before decoding, and
counted per id in ``refused``; a flood of them pauses that count (``refused_partial``), so there
it is checked to have grown, not to be exact.
"""

from __future__ import annotations

import math
import random
import struct
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import msgpack
import pytest
import zenoh

from common.codec import decode, encode
from common.errors import SchemaError
from common.keys import Keys
from common.schema import (
    Blob,
    Features,
    NodeStatus,
    PanoramicModel,
    Pose,
    PtzCommand,
    PtzRequest,
    PtzState,
    SensorInfo,
    ViewPlan,
)
from common.session import SessionSettings, open_session
from tests.integration.test_faults import (
    MANAGER_ID,
    FaultSite,
    Observer,
    _up_to_speed,
    make_fault_site,
    observing,
    running,
)
from tests.support import REPO, ManagedProcess, wait_for

pytestmark = [pytest.mark.integration, pytest.mark.timeout(180)]

N_PAYLOADS = 100_000
OVERSIZE_BYTES = 4 << 20
N_OVERSIZE = 64
N_FAKE_SENSORS = 20_000
RSS_BOUND_MIB = 250.0
"""Most a process may grow at its peak while it is flooded (oversize payloads, made-up sensors)."""
ROUND_GROWTH_MIB = 30.0
"""Most a second, identical round of flooding may add: bounded memory saturates."""

# ---------------------------------------------------------------------------
# Payloads that must fail to decode
# ---------------------------------------------------------------------------


def templates() -> dict[type, bytes]:
    """One valid encoding per message type a hostile payload imitates."""
    blob = Blob(
        local_id=3,
        bearing_rad=0.5,
        width_rad=0.1,
        top_elev_rad=0.2,
        bottom_elev_rad=-0.3,
        bbox_u_px=10.0,
        bbox_v_px=20.0,
        bbox_w_px=30.0,
        bbox_h_px=90.0,
        hist=[1 / 8] * 8,
    )
    msgs: list[Any] = [
        Features(sensor_id="s00", seq=1, stamp_ns=time.time_ns(), frame_index=1, blobs=[blob, blob]),
        SensorInfo(
            sensor_id="s00",
            seq=1,
            stamp_ns=1,
            kind="panoramic",
            model=PanoramicModel(width_px=1080, height_px=162, f_v_px=256.0, v0_px=93.0),
            pose=Pose(x_m=1.0, y_m=2.0, z_m=1.1, yaw_rad=0.3),
            pose_source="surveyed",
        ),
        NodeStatus(
            sensor_id="s00",
            seq=1,
            stamp_ns=1,
            fps=10.0,
            frames=1,
            dropped_frames=0,
            processing_ms=1.0,
            clock_offset_ns=0,
            clock_uncertainty_ns=0,
            clock_source="system",
            decode_errors=0,
            source_state="ok",
        ),
        PtzState(sensor_id="ptz1", seq=1, stamp_ns=1, pan_rad=0.1, tilt_rad=0.0, zoom=1.0),
        PtzCommand(manager_id=MANAGER_ID, seq=1, stamp_ns=1, sensor_id="ptz1", pan_rad=0.2, tilt_rad=-0.1),
        ViewPlan(
            manager_id=MANAGER_ID,
            seq=1,
            stamp_ns=1,
            sensor_id="pano1",
            partner_id="pano3",
            track_id="mgr1-1",
            goal_x_m=2.0,
            goal_y_m=2.0,
            baseline_m=2.0,
            phi1_rad=1.0,
            predicted_error_m=0.1,
            current_error_m=0.3,
        ),
        PtzRequest(agent_id="a1", seq=1, stamp_ns=1, action="acquire", track_id="mgr1-1"),
    ]
    return {type(m): encode(m) for m in msgs}


def _random_obj(rng: random.Random, depth: int = 0) -> Any:
    r = rng.random()
    if depth > 3 or r < 0.3:
        return rng.choice(
            [
                None,
                True,
                rng.randint(-(2**63), 2**64 - 1),
                rng.random() * 1e300,
                math.nan,
                math.inf,
                "x" * rng.randint(0, 40),
                b"\xff" * 3,
            ]
        )
    if r < 0.65:
        return [_random_obj(rng, depth + 1) for _ in range(rng.randint(0, 6))]
    keys = ["type", "sensor_id", "seq", "stamp_ns", "blobs", "bearing_rad", "pan_rad", "zz"]
    return {rng.choice(keys): _random_obj(rng, depth + 1) for _ in range(rng.randint(0, 6))}


def _candidate(rng: random.Random, own: bytes, others: list[bytes]) -> bytes:
    kind = rng.random()
    if kind < 0.25:  # random bytes
        return rng.randbytes(rng.randint(0, 300))
    if kind < 0.55:  # a valid message, mutated
        b = bytearray(own)
        for _ in range(rng.randint(1, 4)):
            op = rng.random()
            i = rng.randrange(len(b)) if b else 0
            if op < 0.5 and b:
                b[i] = rng.randrange(256)
            elif op < 0.75:
                del b[i : i + rng.randint(1, 8)]
            else:
                b[i:i] = rng.randbytes(rng.randint(1, 8))
        return bytes(b)
    if kind < 0.65:  # truncated
        return own[: rng.randrange(len(own))]
    if kind < 0.8:  # well-formed MessagePack of the wrong shape
        return bytes(msgpack.packb(_random_obj(rng), use_bin_type=True))
    if kind < 0.9:  # a valid message of another type (tag confusion)
        return rng.choice(others)
    edge = rng.randrange(5)
    if edge == 0:  # deep nesting
        return b"\x91" * rng.randint(200, 20_000) + b"\xc0"
    if edge == 1:  # an array claiming 2^32-1 items
        return b"\xdd\xff\xff\xff\xff" + rng.randbytes(8)
    if edge == 2:  # a map claiming 2^32-1 pairs
        return b"\xdf\xff\xff\xff\xff"
    if edge == 3:  # NaN where a bounded float goes
        return own.replace(struct.pack(">d", 0.5), struct.pack(">d", math.nan), 1) + b""
    return b""


def hostile_payloads(msg_type: type, n: int, seed: int) -> list[bytes]:
    """``n`` payloads, each of which ``decode(payload, msg_type)`` refuses."""
    rng = random.Random(seed)
    tpl = templates()
    own = tpl[msg_type]
    others = [v for k, v in tpl.items() if k is not msg_type]
    out: list[bytes] = []
    while len(out) < n:
        data = _candidate(rng, own, others)
        try:
            decode(data, msg_type)
        except SchemaError:
            out.append(data)
    return out


def test_hostile_payloads_are_all_refused_by_the_codec() -> None:
    """The generator's own check, and variety: every kind of payload occurs."""
    payloads = hostile_payloads(Features, 2000, seed=1)
    assert len(payloads) == 2000
    assert any(p.startswith(b"\x91\x91") for p in payloads)
    assert any(p == b"" for p in payloads)
    assert len({p[:1] for p in payloads}) > 50
    for p in payloads:
        with pytest.raises(SchemaError):
            decode(p, Features)


# ---------------------------------------------------------------------------
# The flood
# ---------------------------------------------------------------------------


def _rss_mib(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return 0.0


class RssWatch:
    """Peak RSS of some processes over a stretch of time, sampled every 50 ms by the caller."""

    def __init__(self, procs: dict[str, ManagedProcess]) -> None:
        self.procs = procs
        self.base = {n: _rss_mib(p.pid) for n, p in procs.items()}
        self.peak = dict(self.base)

    def sample(self) -> None:
        for n, p in self.procs.items():
            if p.alive:
                self.peak[n] = max(self.peak[n], _rss_mib(p.pid))

    def growth(self) -> dict[str, float]:
        return {n: round(self.peak[n] - self.base[n], 1) for n in self.procs}


def _ptz_node_config(site: FaultSite, prefix: str) -> Path:
    """A simulated PTZ camera of the demo site: it subscribes to its PTZ commands and to every plan."""
    path = site.tmp / "ptz1.toml"
    path.write_text(
        f'[node]\nid = "ptz1"\nprefix = "{prefix}"\n'
        f'[zenoh]\nconnect = ["{site.endpoint}"]\nconnect_timeout_ms = 20000\n'
        f'[source]\nkind = "sim"\nsite = "{REPO}/deploy/sites/demo.toml"\ncamera = "ptz1"\nfps = 5.0\n'
        "[pose]\nx_m = 7.85\ny_m = 5.85\nz_m = 2.5\nyaw_deg = 0.0\n"
    )
    return path


def _counted(statuses: list[Any]) -> int:
    """decode errors + messages dropped by full inboxes, as the last status says."""
    last = statuses[-1]
    return int(last.decode_errors) + int(getattr(last, "dropped_msgs", 0))


def _refused(statuses: list[Any]) -> int:
    return int(statuses[-1].refused_msgs)


def _settled(get: Any, timeout_s: float, what: str) -> int:
    """Wait until the counter stops moving for two status periods; return its value."""
    seen: list[int] = []

    def still() -> bool:
        seen.append(get())
        return len(seen) >= 3 and seen[-1] == seen[-3]

    wait_for(still, timeout_s, what, poll_s=1.0)
    return seen[-1]


Flooded = tuple[FaultSite, Observer, Any, dict[str, ManagedProcess]]


@pytest.fixture
def flooded_site(tmp_path: Path, request: pytest.FixtureRequest) -> Iterator[Flooded]:
    """Router, manager, real detection nodes tracking people, a simulated PTZ node; the attacker's session."""
    with running(make_fault_site(tmp_path, prefix="hostile"), request) as s:
        s.start_router()
        with observing(s) as obs:
            procs = {"manager": s.start_manager()}
            for sid in s.ids:
                procs[sid] = s.start_node(sid)
            procs["ptz1"] = s.start_node("ptz1", _ptz_node_config(s, "hostileptz"))
            _up_to_speed(s, obs)
            with open_session(SessionSettings(mode="client", connect=[s.endpoint])) as attacker:
                yield s, obs, attacker, procs


def _flood(session: Any, plan: list[tuple[str, list[bytes]]]) -> int:
    sent = 0
    pubs = {key: session.declare_publisher(key, congestion_control=zenoh.CongestionControl.BLOCK) for key, _ in plan}
    for key, payloads in plan:
        pub = pubs[key]
        for p in payloads:
            pub.put(p)
            sent += 1
    for pub in pubs.values():
        pub.undeclare()
    return sent


def _node_status(session: Any, key: str) -> list[NodeStatus]:
    got: list[NodeStatus] = []
    sub = session.declare_subscriber(key, lambda s: got.append(decode(s.payload.to_bytes(), NodeStatus)))
    try:
        wait_for(lambda: got, 10.0, f"a status on {key}")
    finally:
        sub.undeclare()
    return got


def test_1e5_hostile_payloads_counted_no_crash_tracking_continues(flooded_site: Flooded) -> None:
    site, obs, attacker, procs = flooded_site

    k = site.keys
    pk = Keys("hostileptz")
    real = site.ids
    t_before = time.monotonic()
    wait_for(lambda: obs.status_since(t_before), 5.0, "a manager status before the flood")
    mgr_before = _counted(obs.status_since(t_before))
    refused_before = _refused(obs.status_since(t_before))
    node_before = _counted(_node_status(attacker, pk.sensor_status("ptz1")))

    # Split 10^5 payloads over every key the manager and the nodes subscribe to.
    share = N_PAYLOADS // 10
    plan = [
        (k.sensor_features(real[0]), hostile_payloads(Features, share, 1)),  # a real camera's key
        (k.sensor_features(real[2]), hostile_payloads(Features, share, 5)),
        (k.sensor_info(real[1]), hostile_payloads(SensorInfo, share, 3)),
        (k.sensor_ptz_state(real[3]), hostile_payloads(PtzState, share, 6)),
    ]
    unlisted = [  # ids the manager does not fuse: refused by key
        (k.sensor_features("evil"), hostile_payloads(Features, share, 2)),
        (k.sensor_info("evil"), hostile_payloads(SensorInfo, share, 4)),
    ]
    node_plan = [
        (pk.sensor_ptz("ptz1"), hostile_payloads(PtzCommand, 2 * share, 7)),
        (pk.plan("pano1"), hostile_payloads(ViewPlan, 2 * share, 8)),
    ]
    n_mgr = sum(len(p) for _, p in plan)
    n_unlisted = sum(len(p) for _, p in unlisted)
    n_node = sum(len(p) for _, p in node_plan)
    assert n_mgr + n_unlisted + n_node == N_PAYLOADS
    rss = RssWatch({n: p for n, p in procs.items() if n in ("manager", "ptz1")})
    t_flood = time.monotonic()
    sent = _flood(attacker, plan + unlisted + node_plan)
    assert sent == N_PAYLOADS
    # Hostile queries on the queryables: the PTZ allocation and a node's info.
    replies = 0
    for i, data in enumerate(hostile_payloads(PtzRequest, 500, 9)):
        for r in attacker.get(k.ptz_request(MANAGER_ID, "a1"), payload=data, timeout=2.0):
            replies += 1 if r.ok is not None or r.err is not None else 0
        if i % 50 == 0:
            rss.sample()
    for data in hostile_payloads(SensorInfo, 100, 10):
        list(attacker.get(k.sensor_info(real[0]), payload=data, timeout=2.0))
    # Malformed history parameters on the track queryable: each answered with an error, none crashes it.
    bad_params = ["abc", "-5", "nan", "inf", "1e309", "", "0x10", "9" * 400, "1;history=2", "\u00e9"]
    errs = 0
    for value in bad_params * 10:
        for r in attacker.get(zenoh.Selector(k.all_tracks, {"history": value}), timeout=2.0):
            errs += 1 if r.err is not None else 0
    assert errs >= 90, f"only {errs} of 100 malformed history queries were answered with an error"
    # Liveliness tokens of made-up sensors, valid ids or not: presence churn must not disturb tracking.
    tokens = [attacker.liveliness().declare_token(k.all_sensors.replace("*", f"ghost{i:04d}")) for i in range(300)]
    tokens += [
        attacker.liveliness().declare_token(f"{k.root}/sensor/{bad}") for bad in ("UPPER", "a_b", "-x", "x" * 60)
    ]
    for t in tokens:
        t.undeclare()

    mgr_after = _settled(
        lambda: _counted(obs.status_since(t_flood)) if obs.status_since(t_flood) else -1,
        60.0,
        "the manager's counters to settle",
    )
    node_after = _settled(
        lambda: _counted(_node_status(attacker, pk.sensor_status("ptz1"))), 60.0, "the node's counters to settle"
    )
    rss.sample()
    for name, p in procs.items():
        assert p.alive, f"{name} died under hostile input:\n{p.log()}"
    assert mgr_after - mgr_before >= n_mgr, f"manager counted {mgr_after - mgr_before} of {n_mgr} bad payloads"
    last = obs.status_since(t_flood)[-1]
    refused = _refused(obs.status_since(t_flood)) - refused_before
    assert refused > 0 and any(r.sender_id == "evil" and r.unlisted > 0 for r in last.refused), last.refused
    if not last.refused_partial:
        assert refused >= n_unlisted, f"{refused} of {n_unlisted} payloads of an unlisted sensor counted"
    assert node_after - node_before >= n_node, f"node counted {node_after - node_before} of {n_node} bad payloads"
    # Tracking of the real data continues, with every real camera.
    t_after = time.monotonic()
    wait_for(lambda: obs.tracking_with(t_after, set(real), min_sets=10), 20.0, "tracking after the flood")
    assert max(rss.growth().values()) < RSS_BOUND_MIB, rss.growth()


FLOODS = ["oversize payloads", "made-up sensors"]


def _flood_round(flood: str, rnd: int, site: FaultSite, attacker: Any, rss: RssWatch) -> None:
    """One round of a flood, sampling RSS as it goes."""
    k = site.keys
    pk = Keys("hostileptz")
    if flood == "oversize payloads":
        big = random.Random(rnd).randbytes(OVERSIZE_BYTES)
        keys = [
            k.sensor_features(site.ids[0]),
            k.sensor_features("evil"),
            k.sensor_info("evil"),
            pk.sensor_ptz("ptz1"),
            pk.plan("pano1"),
        ]
        for i in range(N_OVERSIZE // 2):
            attacker.put(keys[i % len(keys)], big, congestion_control=zenoh.CongestionControl.BLOCK)
            rss.sample()
        return
    blob = Blob(
        local_id=1,
        bearing_rad=0.1,
        width_rad=0.1,
        top_elev_rad=0.1,
        bottom_elev_rad=-0.2,
        bbox_u_px=1.0,
        bbox_v_px=1.0,
        bbox_w_px=5.0,
        bbox_h_px=9.0,
    )
    now = time.time_ns()
    for i in range(N_FAKE_SENSORS // 2):  # valid features, each from a sensor nobody announced
        sid = f"fake{rnd}{i:05d}"
        f = Features(sensor_id=sid, seq=1, stamp_ns=now, frame_index=1, blobs=[blob] * 8)
        attacker.put(k.sensor_features(sid), encode(f), congestion_control=zenoh.CongestionControl.BLOCK)
        if i % 500 == 0:
            rss.sample()


@pytest.mark.parametrize("flood", FLOODS)
def test_floods_stay_bounded_in_memory(flooded_site: Flooded, flood: str) -> None:
    """Two equal rounds of a flood: 4 MiB payloads on every subscribed key, or valid features
    from 10^4 made-up sensors.

    Bounded memory means the second round costs (almost) nothing more than the first: whatever
    a receiver keeps per sensor or per payload must be capped, not grow with the flood.
    """
    site, obs, attacker, procs = flooded_site
    watched = {n: p for n, p in procs.items() if n in ("manager", "ptz1")}
    rss = RssWatch(watched)
    after_round: list[dict[str, float]] = []
    for rnd in range(2):
        _flood_round(flood, rnd, site, attacker, rss)
        t_end = time.monotonic() + 3.0
        while time.monotonic() < t_end:  # a measurement window: the receivers work through the round
            rss.sample()
            time.sleep(0.05)
        after_round.append({n: _rss_mib(p.pid) for n, p in watched.items() if p.alive})
    for name, p in procs.items():
        assert p.alive, f"{name} died under {flood}:\n{p.log()}"
    assert max(rss.growth().values()) < RSS_BOUND_MIB, rss.growth()
    for name in watched:
        second = after_round[1][name] - after_round[0][name]
        assert second < ROUND_GROWTH_MIB, (
            f"{name} grew {second:.1f} MiB more in the second round of {flood}: unbounded "
            f"(RSS after each round: {after_round})"
        )
    t_after = time.monotonic()
    wait_for(lambda: obs.tracking_with(t_after, set(site.ids), min_sets=10), 20.0, "tracking after the flood")
