"""Standby managers (issue 25, item 4): a zone's leader killed with SIGKILL, and a partition that heals.

Real processes on loopback, as in test_faults.py (its site: a router, detection-file nodes, the test as the user
agent): two managers share a zone (``--zone``), one leads and publishes, the other fuses the same frames, silent,
naming its tracks after the leader's. The test measures what an agent sees: when the standby's TrackSets start
after the kill, and how many of the leader's track ids they carry.
"""

from __future__ import annotations

import os
import signal
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from benchmarks.bench_load import make_room
from common.schema import ManagerStatus, TrackSet
from tests.integration.test_faults import (
    CameraHost,
    FaultSite,
    Observer,
    camera_host,
    make_fault_site,
    observing,
    running,
)
from tests.support import ManagedProcess, wait_for
from user_agent.client import AgentClient

pytestmark = [pytest.mark.integration, pytest.mark.timeout(120)]

SENSORS = 4
PEOPLE = 6
SEED = 11
ZONE = "hall"
LEADER, STANDBY = "hall-a", "hall-b"
READY_S = 45.0
"""Deadline for the site to come up and track (a loaded 2-core machine)."""
TAKEOVER_S = 2.0
"""The standby publishes within this long of the leader's kill (the issue's target)."""
LOST_IDS = 1
"""At most this many of the leader's ids may be lost across a takeover. A track the leader confirms in its last
tick before the kill reaches the standby too late to be adopted (it never heard that id): a race no standby can
win. The share kept over many takeovers (the issue's 0.95) is measured by ``benchmarks/bench_zones.py``."""


@pytest.fixture
def zone_site(tmp_path: Path, request: pytest.FixtureRequest) -> Iterator[FaultSite]:
    with running(make_fault_site(tmp_path, "standby", room=make_room(SENSORS, PEOPLE, SEED)), request) as s:
        yield s


def _manager(site: FaultSite, mid: str, *, connect: str | None = None, netns: str | None = None) -> ManagedProcess:
    """A manager of the zone (its own id, state directory and config), fusing the site's cameras."""
    cfg = site.tmp / f"{mid}.toml"
    sensors = ", ".join(f'"{sid}"' for sid in site.ids)
    cfg.write_text(
        f'[manager]\nid = "{mid}"\nprefix = "{site.prefix}"\nrate_hz = 10.0\nzone = "{ZONE}"\n'
        f'state_dir = "{site.tmp / "state" / mid}"\nsensors = [{sensors}]\n'
        f'[zenoh]\nconnect = ["{connect or site.endpoint}"]\nconnect_timeout_ms = 20000\nlease_ms = 2000\n'
    )
    args = [sys.executable, "-m", "panostereo", "manager", "--config", str(cfg)]
    if netns:
        args = ["ip", "netns", "exec", netns, *args]
    return site._spawn(args, mid)


def _status(obs: Observer, mid: str, since: float) -> ManagerStatus | None:
    """The newest status of ``mid`` that arrived after ``since``."""
    got = [m for m in obs.status_since(since) if m.manager_id == mid]
    return got[-1] if got else None


def _role(obs: Observer, mid: str, role: str, leader: str, since: float) -> bool:
    st = _status(obs, mid, since)
    return st is not None and st.zone == ZONE and st.role == role and st.leader_id == leader


def _sets_by(obs: Observer, mid: str, since: float) -> list[tuple[float, TrackSet]]:
    with obs.lock:
        return [(a, m) for a, m in obs.sets if a >= since and m.manager_id == mid]


def _ids(ts: TrackSet) -> set[str]:
    return {t.track_id for t in ts.tracks if t.state == "confirmed"}


def _takeover(obs: Observer, victim: ManagedProcess, old: str, new: str) -> tuple[float, int]:
    """SIGKILL the leader ``old``; wait for ``new``'s TrackSets. Returns (seconds from the kill to the first
    TrackSet of ``new``, how many of ``old``'s last confirmed ids are missing from ``new``'s first second of
    tracks)."""
    before = _sets_by(obs, old, 0.0)
    assert before, f"{old} published nothing before the kill"
    t_kill = time.monotonic()
    os.kill(victim.pid, signal.SIGKILL)
    victim.wait(5.0)
    last = _ids(before[-1][1])
    first = wait_for(lambda: _sets_by(obs, new, t_kill), 10.0, f"{new} to publish after {old} was killed")
    took_s = first[0][0] - t_kill
    wait_for(lambda: _sets_by(obs, new, first[0][0] + 1.0), 10.0, f"a second of {new}'s tracks")
    after = set().union(*(_ids(m) for a, m in _sets_by(obs, new, t_kill) if a <= first[0][0] + 1.0))
    print(f"takeover {old} -> {new}: {took_s:.3f} s, {len(last & after)}/{len(last)} ids kept ({sorted(last - after)})")
    return took_s, len(last - after)


def _standing_by(site: FaultSite, obs: Observer, proc: ManagedProcess, mid: str, leader: str) -> None:
    """Wait until ``mid`` stands by for ``leader`` and has named its tracks after the leader's."""
    t0 = time.monotonic()
    wait_for(lambda: _role(obs, mid, "standby", leader, t0), READY_S, f"{mid} to stand by for {leader}")
    proc.wait_for_output(rf"standby {mid} follows {leader}: \d+ tracks renamed", READY_S)
    t1 = time.monotonic()
    # Two more seconds of both fusing: the standby's tracks settle on the leader's ids.
    wait_for(lambda: len(_sets_by(obs, leader, t1)) >= 20, 20.0, f"two seconds of {leader}'s tracks")
    assert not _sets_by(obs, mid, t0), f"{mid} published while standing by"


def test_standby_takes_over_after_sigkill_with_the_same_ids(zone_site: FaultSite) -> None:
    site = zone_site
    site.start_router()
    with observing(site) as obs:
        for sid in site.ids:
            site.start_node(sid)
        a = _manager(site, LEADER)
        t0 = time.monotonic()
        wait_for(lambda: _role(obs, LEADER, "leader", LEADER, t0), READY_S, f"{LEADER} to lead")
        wait_for(lambda: obs.tracking_with(t0, set(site.ids), min_sets=10), READY_S, "confirmed tracks")
        b = _manager(site, STANDBY)
        _standing_by(site, obs, b, STANDBY, LEADER)
        took_s, lost = _takeover(obs, a, LEADER, STANDBY)
        assert took_s < TAKEOVER_S, took_s
        assert lost <= LOST_IDS, lost
        _ptz_goes_to(site, STANDBY)
        # The killed leader, restarted, finds a leader and stands by; killed in turn, that one hands back.
        t_back = time.monotonic()
        a = _manager(site, LEADER)
        _standing_by(site, obs, a, LEADER, STANDBY)
        assert _role(obs, STANDBY, "leader", STANDBY, t_back)
        took_s, lost = _takeover(obs, b, STANDBY, LEADER)
        assert took_s < TAKEOVER_S, took_s
        assert lost <= LOST_IDS, lost


def _ptz_goes_to(site: FaultSite, mid: str) -> None:
    """An agent's PTZ request for a track under the old leader's id reaches the manager publishing it now."""
    with AgentClient(connect=[site.endpoint], prefix=site.prefix, agent_id="ptz-asker") as agent:
        tracks = wait_for(lambda: agent.track_sets(timeout_s=1.0).get(mid), 10.0, f"{mid}'s TrackSets").tracks
        adopted = [t.track_id for t in tracks if not t.track_id.startswith(f"{mid}-")]
        assert adopted, [t.track_id for t in tracks]
        reply = agent.request_view(adopted[0])
        assert reply.manager_id == mid, reply  # no PTZ camera here: the answer says so, from the new leader
        assert not reply.ok and reply.reason


def _one_leader(obs: Observer, since: float) -> str | None:
    """The one manager both statuses name as the zone's leader, since ``since``; None while they disagree."""
    a, b = _status(obs, LEADER, since), _status(obs, STANDBY, since)
    if a is None or b is None or a.leader_id != b.leader_id:
        return None
    roles = sorted((a.role, b.role))
    return a.leader_id if roles == ["leader", "standby"] else None


def test_partition_heals_to_exactly_one_leader(zone_site: FaultSite) -> None:
    """The leader's host is cut off from the router for 5 s (a network namespace whose veth goes down): the
    standby takes over; when the link comes back both lead, until the older term yields to the newer."""
    site = zone_site
    host: CameraHost
    with camera_host() as host:
        site.start_router(f"tcp/{host.here_ip}:{site.port}")
        with observing(site) as obs:
            for sid in site.ids:
                site.start_node(sid)
            _manager(site, LEADER, connect=f"tcp/{host.here_ip}:{site.port}", netns=host.ns)
            t0 = time.monotonic()
            wait_for(lambda: _role(obs, LEADER, "leader", LEADER, t0), READY_S, f"{LEADER} to lead")
            wait_for(lambda: obs.tracking_with(t0, set(site.ids), min_sets=10), READY_S, "confirmed tracks")
            b = _manager(site, STANDBY)
            _standing_by(site, obs, b, STANDBY, LEADER)
            host.cut()
            t_cut = time.monotonic()
            wait_for(lambda: _role(obs, STANDBY, "leader", STANDBY, t_cut), 10.0, f"{STANDBY} to lead while cut")
            wait_for(lambda: _sets_by(obs, STANDBY, t_cut), 5.0, f"{STANDBY}'s tracks")
            wait_for(lambda: time.monotonic() - t_cut >= 5.0, 6.0, "five seconds of partition")
            host.heal()
            t_heal = time.monotonic()
            # The cut-off leader comes back still leading its old term; it yields to the newer one.
            wait_for(lambda: _role(obs, LEADER, "standby", STANDBY, t_heal), 30.0, f"{LEADER} to yield")
            t_one = time.monotonic()
            wait_for(lambda: _one_leader(obs, t_one) == STANDBY, 5.0, "both to name one leader")
            wait_for(lambda: len(_sets_by(obs, STANDBY, t_one)) >= 20, 10.0, "two more seconds of tracks")
            late = _sets_by(obs, LEADER, t_cut)
            print(f"partition: {LEADER} yielded {t_one - t_heal:.2f} s after the heal; {len(late)} sets of it after")
            assert not _sets_by(obs, LEADER, t_one), f"{LEADER} published after it stood by"
            assert _one_leader(obs, t_one) == STANDBY
            # No id published by both at once: every set of the yielded leader after the cut is one it sent
            # before it heard the newer term, and shares no id with the standby's sets of the same instants.
            for arrived, ts in late:
                near = [m for a, m in _sets_by(obs, STANDBY, arrived - 0.2) if a <= arrived + 0.2]
                shared = _ids(ts) & set().union(*(_ids(m) for m in near))
                assert not shared, (arrived - t_heal, sorted(shared))
