"""Handoff between zones (issue 25, items 1-3): two zone managers, a person walking across their border keeps the
id, and at each instant one manager publishes them; an agent sees one site.

Real processes on loopback (test_faults.py's site: a router, detection-file nodes, the test as the user agent): a
10 m room cut in two along x = 5 m, the two people walking back and forth across the border. Each manager
(``--site F --zone Z``) fuses the cameras that see into its zone (here all four see the whole room) and publishes
only the people it owns. The test matches every published track to the person it follows (the walkers' true
positions at its instant) and counts, per person and frame instant, which managers published them. A second test
gives the west zone a standby and kills its leader with SIGKILL mid-run.
"""

from __future__ import annotations

import itertools
import json
import os
import signal
import subprocess
import sys
import time
from collections import defaultdict
from collections.abc import Iterator
from dataclasses import dataclass, replace
from pathlib import Path

import pytest

from benchmarks.bench_load import Cam, Walker, make_room
from common.schema import TrackSet
from tests.integration.test_faults import FPS, LOOP_S, FaultSite, Observer, make_fault_site, observing, running
from tests.support import ManagedProcess, wait_for
from user_agent.client import AgentClient

pytestmark = [pytest.mark.integration, pytest.mark.timeout(120)]

SEED = 5
BORDER_X = 5.0
BAND_M = 1.0
ZONES = {"west": (0.0, BORDER_X), "east": (BORDER_X, 10.0)}
READY_S = 45.0
WATCH_S = 18.0
"""How long the crossings are watched (each person crosses every ~6 s)."""
MATCH_M = 1.0
"""A published track follows the person nearest it within this (the people stay ~3 m apart)."""
MAX_TWICE = 0.02
"""Largest share of person-instants published by both managers."""
MIN_KEPT = 0.9
"""Smallest share of crossings that keep the id (the issue's target is 0.99 on its benchmark)."""


def _walkers() -> tuple[list[Cam], list[Walker]]:
    """The room's four cameras; two people walking west-east across the border, on lines 3 m apart."""
    cams, people = make_room(4, 2, SEED)
    walkers = [
        replace(people[0], x0_m=1.5, y0_m=3.5, x1_m=8.5, y1_m=3.5, speed_mps=1.2, phase_s=0.0),
        replace(people[1], x0_m=8.5, y0_m=6.5, x1_m=1.5, y1_m=6.5, speed_mps=1.0, phase_s=2.0),
    ]
    return cams, walkers


@pytest.fixture
def zone_site(tmp_path: Path, request: pytest.FixtureRequest) -> Iterator[FaultSite]:
    with running(make_fault_site(tmp_path, "handoff", room=_walkers()), request) as s:
        yield s


def _manager(site: FaultSite, zone: str, site_file: Path, mid: str = "") -> ManagedProcess:
    """Manager ``mid`` (default: named like its zone) of ``zone``, run from the site file."""
    mid = mid or zone
    cfg = site.tmp / f"{mid}.toml"
    cfg.write_text(
        f'[manager]\nid = "{mid}"\nprefix = "{site.prefix}"\nrate_hz = 10.0\nstate_dir = "{site.tmp / mid}"\n'
        f'[zenoh]\nconnect = ["{site.endpoint}"]\nconnect_timeout_ms = 20000\nlease_ms = 2000\n'
    )
    args = [sys.executable, "-m", "panostereo", "manager", "--config", str(cfg), "--site", str(site_file)]
    return site._spawn([*args, "--zone", zone], mid)


@dataclass(frozen=True, slots=True)
class Seen:
    """One published track matched to the person it follows."""

    person: int
    frame: int
    manager: str
    track_id: str
    true_x: float


def _matched(site: FaultSite, sets: list[TrackSet]) -> list[Seen]:
    out = []
    for ts in sets:
        t_s = (ts.stamp_ns - site.epoch_ns) / 1e9 % LOOP_S
        truth = [w.at(t_s) for w in site.walkers]
        for tr in ts.tracks:
            if tr.state != "confirmed":
                continue
            d = [((tr.x_m - x) ** 2 + (tr.y_m - y) ** 2) ** 0.5 for x, y in truth]
            p = min(range(len(d)), key=d.__getitem__)
            if d[p] <= MATCH_M:
                frame = round((ts.stamp_ns - site.epoch_ns) * FPS / 1e9)
                out.append(Seen(p, frame, ts.manager_id, tr.track_id, truth[p][0]))
    return out


@dataclass
class Handoffs:
    instants: int = 0
    twice: int = 0
    gaps: int = 0
    crossings: int = 0
    kept: int = 0
    across: str = ""
    """An id published by both managers (one person's, across a handoff)."""


def _score(seen: list[Seen]) -> Handoffs:
    """Per person and frame: which managers published them; per crossing (from one zone's far side, beyond the band,
    to the other's): the id before and after."""
    out = Handoffs()
    for p in {s.person for s in seen}:
        frames: dict[int, list[Seen]] = defaultdict(list)
        for s in seen:
            if s.person == p:
                frames[s.frame].append(s)
        ks = sorted(frames)
        out.instants += len(ks)
        out.twice += sum(1 for k in ks if len({s.manager for s in frames[k]}) > 1)
        out.gaps += sum(1 for a, b in itertools.pairwise(ks) if b - a > 1)
        side, last_id = 0, ""
        for k in ks:
            s = frames[k][0]
            here = -1 if s.true_x < BORDER_X - BAND_M - 0.5 else 1 if s.true_x > BORDER_X + BAND_M + 0.5 else 0
            if here and side and here != side:
                out.crossings += 1
                out.kept += s.track_id == last_id
            if here:
                side, last_id = here, s.track_id
        by_id: dict[str, set[str]] = defaultdict(set)
        for s in seen:
            by_id[s.track_id].add(s.manager)
        out.across = out.across or next((tid for tid, ms in by_id.items() if len(ms) > 1), "")
    return out


def _sets_of(obs: Observer, since: float, managers: set[str]) -> list[TrackSet]:
    with obs.lock:
        return [m for a, m in obs.sets if a >= since and m.manager_id in managers]


def _judged(got: Handoffs, what: str) -> Handoffs:
    """Print the run's figures and hold it to the goals: crossings happened, kept their ids, nobody twice."""
    print(
        f"{what}: {got.instants} person-instants, {got.twice} published twice, {got.gaps} gaps, "
        f"{got.kept}/{got.crossings} crossings kept the id"
    )
    assert got.crossings >= 3, got
    assert got.kept / got.crossings >= MIN_KEPT, got
    assert got.twice / got.instants <= MAX_TWICE, got
    return got


def _everyone(site: FaultSite, obs: Observer) -> bool:
    """Every person was published at each of the last ten instants (the tracks confirmed and settled)."""
    seen = _matched(site, _sets_of(obs, time.monotonic() - 2.0, set(ZONES)))
    if not seen:
        return False
    last = max(s.frame for s in seen)
    return all(len({s.frame for s in seen if s.person == p and s.frame > last - 10}) == 10 for p in range(2))


def test_a_person_crossing_zones_keeps_the_id_and_is_published_once(zone_site: FaultSite) -> None:
    site = zone_site
    site_file = site.zoned_site_file("handoff", ZONES, reach_m=12, band_m=BAND_M)
    site.start_router()
    with observing(site) as obs:
        for sid in site.ids:
            site.start_node(sid)
        for zone in ZONES:
            _manager(site, zone, site_file)
        t0 = time.monotonic()
        wait_for(lambda: {m.manager_id for m in obs.sets_since(t0) if m.tracks} == set(ZONES), READY_S, "both zones")
        wait_for(lambda: _everyone(site, obs), READY_S, "every person published for a second")
        t1 = time.monotonic()
        wait_for(lambda: time.monotonic() - t1 >= WATCH_S, WATCH_S + 5.0, "the crossings")
        seen = _matched(site, _sets_of(obs, t1, set(ZONES)))
        got = _judged(_score(seen), "handoff")
        assert got.across, "no id was published by both managers: no handoff happened"
        _agent_sees_one_site(site, got.across)


def _agent_sees_one_site(site: FaultSite, across: str) -> None:
    """``agent tracks``: one row per person; ``agent history ID``: the path from both managers, in time."""
    with AgentClient(connect=[site.endpoint], prefix=site.prefix, agent_id="handoff-agent") as agent:
        rows = wait_for(lambda: agent.tracks(timeout_s=1.0), 10.0, "tracks")
        ids = [t.track_id for t in rows]
        assert len(ids) == len(set(ids)) and len(ids) <= len(site.walkers) + 1, ids
        path = agent.history(across, 60.0)
        assert {t.manager_id for t in path} == set(ZONES), {t.manager_id for t in path}
        stamps = [t.stamp_ns for t in path]
        assert stamps == sorted(set(stamps))
    net = ["--prefix", site.prefix, "--connect", site.endpoint]
    out = subprocess.run(
        [sys.executable, "-m", "user_agent", "history", across, "--seconds", "60", "--json", *net],
        capture_output=True,
        text=True,
        timeout=30,
        check=True,
    )
    states = json.loads(out.stdout)
    assert {s["manager_id"] for s in states} == set(ZONES), out.stdout[:400]


def test_a_zones_standby_takes_over_its_people_with_their_ids(zone_site: FaultSite) -> None:
    """The west zone has a leader and a standby; the leader is killed with SIGKILL while people cross: the standby
    publishes the west's people under the same ids, and the crossings go on, each person published once."""
    site = zone_site
    site_file = site.zoned_site_file("handoff", ZONES, reach_m=12, band_m=BAND_M)
    site.start_router()
    with observing(site) as obs:
        for sid in site.ids:
            site.start_node(sid)
        leader = _manager(site, "west", site_file)
        _manager(site, "east", site_file)
        t0 = time.monotonic()
        wait_for(lambda: {m.manager_id for m in obs.sets_since(t0) if m.tracks} == set(ZONES), READY_S, "both zones")
        standby = _manager(site, "west", site_file, mid="west-b")
        standby.wait_for_output(r"standby west-b follows west: \d+ tracks renamed", READY_S)
        wait_for(lambda: _everyone(site, obs), READY_S, "every person published for a second")
        t1 = time.monotonic()
        wait_for(lambda: time.monotonic() - t1 >= WATCH_S / 2, WATCH_S, "crossings before the kill")
        os.kill(leader.pid, signal.SIGKILL)
        leader.wait(5.0)
        t_kill = time.monotonic()
        wait_for(lambda: _sets_of(obs, t_kill, {"west-b"}), 10.0, "the standby to publish")
        wait_for(lambda: time.monotonic() - t_kill >= WATCH_S / 2, WATCH_S, "crossings after the kill")
        managers = {*ZONES, "west-b"}
        _judged(_score(_matched(site, _sets_of(obs, t1, managers))), "handoff with a takeover")
