"""Trust, third round (issue 24), on one secured site: what a valid certificate can still do, and cannot.

A real site on loopback with TLS, mutual TLS and the access rules of ``deploy/security/make-certs.sh`` and
``make_configs.py``: a ``panostereo router``, a manager, four detection nodes tracking three people
(tests/integration/test_faults.py's room), and three sensors this test plays with their own certificates: a
panoramic camera on a post (``post``, surveyed) that sights a robot (``bot``, placed by mutual calibration) far
off the room, and a PTZ camera ``z1``. Agents ``a1`` and ``a2`` have the default PTZ priority cap, ``ops`` a cap of
10 (``--agents "a1 a2 ops:10"``, whose ``ptz-priorities.toml`` goes into the manager's config as the README says).

* post's certificate, the real post stopped, says over and over that bot stands 0.6 m away: bot's pose does not
  move (its own node reports no motion), and post's sightings are refused and counted;
* an agent's PTZ priority is clipped to its cap, and a refusal names no holder;
* an agent flooding PTZ requests writes a bounded log (one line a second);
* a valid camera flooding its own key with the largest Features for 10 s: the manager's and the router's memory
  are back within 10 % of before 10 s after, and tracking is back within 2 s.

Floors are what the issue asks; times are measured from what the processes say, not slept.
"""

from __future__ import annotations

import contextlib
import json
import math
import re
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from benchmarks.bench_flood import recall_of
from common.codec import encode
from common.keys import Keys
from common.schema import ManagerStatus, PinholeModel, Pose, SensorInfo
from common.session import MSGPACK, SessionSettings, open_session
from tests.integration.test_faults import (
    LOOP_S,
    MANAGER_ID,
    FaultSite,
    Observer,
    _up_to_speed,
    make_fault_site,
    observing_session,
)
from tests.support import REPO, ManagedProcess, wait_for, wait_for_port
from tests.unit.resource_manager.synth import Cam, features_for, info_for

pytestmark = [pytest.mark.integration, pytest.mark.timeout(300)]

SECURITY = REPO / "deploy" / "security"
SCRIPTED = ("post", "bot", "z1")
"""The sensors this test plays (with their own certificates)."""
POST = Cam("post", 300.0, 300.0, yaw=0.3)
BOT = Cam("bot", 303.0, 300.5, yaw=1.0, mobile=True, surveyed=False)
FORGED_BOT = Cam("bot", 303.0, 301.1, yaw=1.0, mobile=True, surveyed=False)
"""Where the stolen post says bot is: 0.6 m from where it stands (the issue's attack)."""
Z1 = SensorInfo(
    sensor_id="z1",
    seq=1,
    stamp_ns=1,
    kind="ptz",
    model=PinholeModel(width_px=640, height_px=480, k=[500.0, 0, 320, 0, 500, 240, 0, 0, 1]),
    pose=Pose(x_m=0.2, y_m=0.2, z_m=2.5, yaw_rad=0.0),
    pose_source="surveyed",
)


def _run(args: list[str]) -> str:
    res = subprocess.run(args, cwd=REPO, capture_output=True, text=True, timeout=120, check=False)
    assert res.returncode == 0, f"{args} failed:\n{res.stdout}\n{res.stderr}"
    return res.stdout


def _rss_mb(pid: int) -> float:
    m = re.search(r"^VmRSS:\s+(\d+) kB", Path(f"/proc/{pid}/status").read_text(), re.M)
    assert m is not None
    return int(m.group(1)) / 1024


@dataclass
class Played:
    """A sensor this test plays: its token, its SensorInfo queryable and (panoramic) 10 Hz Features."""

    session: Any
    keys: Keys
    info: SensorInfo
    world: list[Cam] = field(default_factory=list)
    """What it sees (panoramic: the bodies it sights); empty: it publishes no Features."""
    stop: threading.Event = field(default_factory=threading.Event)

    def start(self) -> None:
        sid = self.info.sensor_id
        self._token = self.session.liveliness().declare_token(self.keys.sensor(sid))

        def on_query(q: Any) -> None:
            with q:
                q.reply(self.keys.sensor_info(sid), encode(self.info), encoding=MSGPACK)

        self._queryable = self.session.declare_queryable(self.keys.sensor_info(sid), on_query)
        if self.world:
            threading.Thread(target=self._publish, name=f"played-{sid}", daemon=True).start()

    def _publish(self) -> None:
        rng = np.random.default_rng(0)
        seq = 0
        me = self.info.sensor_id
        while not self.stop.wait(0.1):
            seq += 1
            cam = next(c for c in self.world if c.id == me)
            f = features_for(cam, [], self.world, time.time_ns(), seq, rng)
            self.session.put(self.keys.sensor_features(me), encode(f), encoding=MSGPACK)


@dataclass
class TrustSite:
    fsite: FaultSite
    cfg: Path
    obs: Observer
    played: dict[str, Played]
    manager: ManagedProcess
    router: ManagedProcess

    def settings(self, name: str) -> SessionSettings:
        return SessionSettings(
            mode="client", config_file=str(self.cfg / f"{name}.json5"), connect=[self.fsite.endpoint]
        )

    def status_after(self, t0: float) -> ManagerStatus:
        return wait_for(lambda: (self.obs.status_since(t0) or [None])[-1], 10.0, "a manager status")


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TrustSite]:
    tmp = tmp_path_factory.mktemp("trust")
    fsite = make_fault_site(tmp, prefix="trust")
    certs, cfg = tmp / "certs", tmp / "cfg"
    sensors = " ".join([*fsite.ids, *SCRIPTED])
    _run(["bash", str(SECURITY / "make-certs.sh"), "--out", str(certs), "--sensors", sensors, "--managers",
          MANAGER_ID, "--agents", "a1 a2 ops:10"])  # fmt: skip
    _run([sys.executable, str(SECURITY / "make_configs.py"), "--certs", str(certs), "--out", str(cfg), "--prefix",
          fsite.prefix, "--sensors", sensors, "--managers", MANAGER_ID, "--agents", "a1 a2 ops:10", "--listen",
          f"tls/127.0.0.1:{fsite.port}", "--tls-only"])  # fmt: skip
    fsite.connect_to = f"tls/localhost:{fsite.port}"
    manager_cfg = fsite.manager_config(extra_sensors=SCRIPTED)
    manager_cfg.write_text(manager_cfg.read_text() + "\n" + (cfg / "ptz-priorities.toml").read_text())
    stack = contextlib.ExitStack()
    played: dict[str, Played] = {}
    try:
        router = fsite._spawn(
            [sys.executable, "-m", "panostereo", "router", "--zenoh-config", str(cfg / "router-tls.json5")], "router"
        )
        wait_for_port(fsite.port, 20.0, proc=router)
        manager = fsite.start_manager(manager_cfg, extra=("--zenoh-config", str(cfg / f"manager-{MANAGER_ID}.json5")))
        for sid in fsite.ids:
            fsite.start_node(sid, extra=("--zenoh-config", str(cfg / f"sensor-{sid}.json5")))
        keys = Keys(fsite.prefix)
        for sid, info, world in (("post", info_for(POST), [POST, BOT]), ("bot", info_for(BOT), [POST, BOT]),
                                 ("z1", Z1, [])):  # fmt: skip
            s = stack.enter_context(
                open_session(
                    SessionSettings(
                        mode="client", config_file=str(cfg / f"sensor-{sid}.json5"), connect=[fsite.endpoint]
                    )
                )
            )
            played[sid] = Played(s, keys, info, world)
            played[sid].start()
        watcher = stack.enter_context(
            open_session(
                SessionSettings(mode="client", config_file=str(cfg / "agent-a1.json5"), connect=[fsite.endpoint])
            )
        )
        with observing_session(watcher, fsite) as obs:
            ts = TrustSite(fsite, cfg, obs, played, manager, router)
            try:
                _up_to_speed(fsite, obs)
            except AssertionError as err:
                raise AssertionError(f"{err}\n{fsite.logs()}") from err
            yield ts
    finally:
        for p in played.values():
            p.stop.set()
        stack.close()
        fsite.stop_all()


def _bot_pose(st: ManagerStatus) -> tuple[float, float, float] | None:
    est = next((p for p in st.poses if p.sensor_id == "bot"), None)
    return None if est is None else (est.pose.x_m, est.pose.y_m, est.pose.yaw_rad)


def _sightings_refused(st: ManagerStatus, sender: str) -> int:
    return sum(r.sighting for r in st.refused if r.sender_id == sender)


def test_a_stolen_camera_cannot_move_another_and_is_counted(site: TrustSite) -> None:
    # bot placed by mutual calibration from post's sightings, then settled (its node reports no motion).
    t0 = time.monotonic()
    wait_for(lambda: _bot_pose(site.status_after(t0)) is not None, 20.0, "bot placed by mutual calibration")
    wait_for(lambda: len(site.obs.status_since(t0)) >= 6, 15.0, "6 s of statuses: bot's pose settled")
    before = _bot_pose(site.status_after(time.monotonic()))
    assert before is not None and math.hypot(before[0] - BOT.x, before[1] - BOT.y) < 0.15, before
    refused_before = _sightings_refused(site.status_after(t0), "post")
    # The real post stops; its certificate says, consistently, 10 times a second, that bot stands 0.6 m away.
    site.played["post"].world = [POST, FORGED_BOT]
    t1 = time.monotonic()
    wait_for(lambda: len(site.obs.status_since(t1)) >= 5, 15.0, "5 s of forged sightings")
    during = [p for st in site.obs.status_since(t1) if (p := _bot_pose(st)) is not None]
    assert during, "bot's pose was lost under the forgery"
    worst = max(math.hypot(x - before[0], y - before[1]) for x, y, _ in during)
    turn = max(abs(math.remainder(yaw - before[2], 2 * math.pi)) for _, _, yaw in during)
    assert worst < 0.05 and turn < 0.01, f"one camera moved another: {worst:.3f} m, {turn:.4f} rad"
    last = site.status_after(t1)
    assert _sightings_refused(last, "post") >= refused_before + 20, last.refused
    site.played["post"].world = [POST, BOT]  # the real post is back


def test_an_agents_ptz_priority_is_clipped_to_its_cap_and_a_refusal_names_no_holder(site: TrustSite) -> None:
    from user_agent.client import AgentClient

    tid = wait_for(
        lambda: next((t.track_id for s in site.obs.sets_since(time.monotonic() - 2) for t in s.tracks
                      if t.state == "confirmed"), None),
        10.0,
        "a confirmed track",
    )  # fmt: skip
    a1 = AgentClient(settings=site.settings("agent-a1"), prefix=site.fsite.prefix, agent_id="a1")
    a2 = AgentClient(settings=site.settings("agent-a2"), prefix=site.fsite.prefix, agent_id="a2")
    ops = AgentClient(settings=site.settings("agent-ops"), prefix=site.fsite.prefix, agent_id="ops")
    with a1, a2, ops:
        got = wait_for(lambda: (r := a1.request_view(tid, priority=5, manager_id=MANAGER_ID)).ok and r, 10.0,
                       "a1's view (z1 known to the manager)")  # fmt: skip
        assert got.sensor_id == "z1" and "clipped to 0" in got.reason, got
        refused = a2.request_view(tid, priority=999, manager_id=MANAGER_ID)
        assert not refused.ok and "clipped to 0" in refused.reason, refused
        assert "a1" not in refused.reason and " 5" not in refused.reason, f"the refusal tells too much: {refused}"
        taken = ops.request_view(tid, priority=50, manager_id=MANAGER_ID)
        assert taken.ok and taken.sensor_id == "z1" and "clipped to 10" in taken.reason, taken
        ops.release_view(tid, manager_id=MANAGER_ID)


def test_a_ptz_request_flood_writes_a_bounded_log(site: TrustSite) -> None:
    def a2_lines() -> list[str]:
        return [ln for ln in site.manager.log().splitlines() if "by a2" in ln or "from a2" in ln]

    before = len(a2_lines())
    out = _run([sys.executable, "-m", "benchmarks.hostile", "flood", "--connect", site.fsite.endpoint, "--prefix",
                site.fsite.prefix, "--zenoh-config", str(site.cfg / "agent-a2.json5"), "--manager", MANAGER_ID,
                "--ptz-agent", "a2", "--duration", "4"])  # fmt: skip
    sent = json.loads(out.splitlines()[-1])
    assert sent["ptz_requests"] >= 200, sent  # a flood: far more than one line a second could say
    t0 = time.monotonic()
    wait_for(lambda: len(site.obs.status_since(t0)) >= 2, 10.0, "the manager's next statuses (its log flushed)")
    lines = a2_lines()[before:]
    per_second: dict[str, int] = {}
    for ln in lines:
        per_second[ln[:8]] = per_second.get(ln[:8], 0) + 1  # HH:MM:SS
    # One line per second for the sender, and at most one more saying how many were not logged.
    assert lines and max(per_second.values()) <= 2, f"{len(lines)} lines for {sent['ptz_requests']} requests: {lines}"
    assert len(lines) <= 0.05 * sent["ptz_requests"], lines


def test_a_max_size_features_flood_leaves_no_residue_and_tracking_is_back_within_2_s(site: TrustSite) -> None:
    fs = site.fsite
    flooded = fs.ids[0]

    def rss() -> tuple[float, float]:
        return _rss_mb(site.manager.pid), _rss_mb(site.router.pid)

    t0 = time.monotonic()
    wait_for(lambda: len(site.obs.status_since(t0)) >= 3, 10.0, "3 s of steady state")
    before = rss()
    recalls = [recall_of(s, fs.walkers, fs.epoch_ns, LOOP_S) for s in site.obs.sets_since(t0)]
    base = sum(recalls) / len(recalls)
    peak = [0.0, 0.0]
    sampling = threading.Event()

    def sample() -> None:
        while not sampling.wait(0.5):
            now = rss()
            peak[0], peak[1] = max(peak[0], now[0]), max(peak[1], now[1])

    threading.Thread(target=sample, daemon=True).start()
    out = _run([sys.executable, "-m", "benchmarks.hostile", "flood", "--connect", fs.endpoint, "--prefix", fs.prefix,
                "--zenoh-config", str(site.cfg / f"sensor-{flooded}.json5"), "--real", flooded, "--max-size",
                "--duration", "10"])  # fmt: skip
    ended = time.monotonic()
    sampling.set()
    sent = json.loads(out.splitlines()[-1])
    assert sent["rate_hz"] >= 100 and sent["bytes"] > 150_000, sent
    # Tracking is back within 2 s: TrackSets fusing the flooded camera again, finding the people as before.
    wait_for(lambda: any(s for s in site.obs.sets_since(ended + 2.0)), 10.0, "TrackSets after the flood")
    back = [s for a, s in site.obs.sets if ended <= a <= ended + 2.0]
    good = [
        s for s in back if flooded in s.sensors_used and recall_of(s, fs.walkers, fs.epoch_ns, LOOP_S) >= 0.8 * base
    ]
    print(f"recall before {base:.2f}; first good TrackSet after the flood: {bool(good)}")
    assert good, f"not back within 2 s of the flood: {[(s.sensors_used, len(s.tracks)) for s in back]}"
    # Memory back within 10 % of before, 10 s after.
    wait_for(lambda: time.monotonic() >= ended + 10.0 and bool(site.obs.status_since(ended + 9.0)), 20.0,
             "10 s after the flood")  # fmt: skip
    after = rss()
    detail = (
        f"manager {before[0]:.0f} -> {peak[0]:.0f} -> {after[0]:.0f} MB, "
        f"router {before[1]:.0f} -> {peak[1]:.0f} -> {after[1]:.0f} MB"
    )
    assert after[0] <= 1.1 * before[0] and after[1] <= 1.1 * before[1], detail
    print(detail)
