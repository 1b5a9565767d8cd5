"""The manager's shell, without a zenoh session (its loopback runs are tests/integration's): a manager's seat in
its zone reads the zone's seats whole, and a read the router did not answer is not a whole view; a zone's standby
names its people as the leader does."""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from common.area import Area, rectangle
from common.keys import Keys
from common.schema import TrackSet
from common.session import Shutdown, wait_until
from resource_manager.fusion import Batch, Fusion
from resource_manager.node import ZoneSeat, standby_names
from resource_manager.serve.zones import ZoneOwnership
from tests.unit.common.tracks import published
from tests.unit.resource_manager.scenario import T0_NS, make_config
from tests.unit.resource_manager.synth import Cam, Person, features_for, info_for

ZONE = "hall"
KEYS = Keys()


@dataclass
class _Key:
    key_expr: str


@dataclass
class _Reply:
    """A liveliness ``get`` reply as zenoh gives it: a token (``ok``) or an error (``err``, e.g. a timeout)."""

    ok: _Key | None = None
    err: str | None = None


class _Token:
    def undeclare(self) -> None:
        pass


class _Liveliness:
    """The zone's seats as a router answers for them: ``first`` to the first two reads (at start, and once the
    sensors' frames are there), then ``slow`` until the test moves on to ``then``."""

    def __init__(self, first: list[_Reply], slow: list[_Reply], then: list[_Reply]) -> None:
        self.first, self.slow, self.then = first, slow, then
        self.moved_on = threading.Event()
        self.gets = 0
        self.lock = threading.Lock()

    def declare_token(self, key: str) -> _Token:
        return _Token()

    def declare_subscriber(self, key: str, callback: Callable[[Any], None]) -> object:
        return object()

    def get(self, key: str, timeout: float) -> list[_Reply]:
        with self.lock:
            self.gets += 1
            if self.gets <= 2:
                return self.first
        return self.then if self.moved_on.is_set() else self.slow


class _Session:
    def __init__(self, live: _Liveliness) -> None:
        self.live = live

    def liveliness(self) -> _Liveliness:
        return self.live


def _seat(mid: str, term: int = 0) -> _Reply:
    key = KEYS.zone_leader(mid, ZONE, term) if term else KEYS.zone_standby(mid, ZONE)
    return _Reply(ok=_Key(key))


def test_a_read_the_router_did_not_answer_does_not_make_a_standby_claim() -> None:
    """zenoh answers a liveliness ``get`` whose router is slow with this session's own tokens and a timeout error.
    Taken as a whole view it would say the leader went; the standby claimed over it (a second leader on a busy
    host). It reads again instead, and claims only once a whole view shows the leader gone."""
    live = _Liveliness(
        first=[_seat("a"), _seat("b", term=2)], slow=[_seat("a"), _Reply(err="Timeout")], then=[_seat("a")]
    )
    checks = 0

    def can_lead() -> bool:
        nonlocal checks
        checks += 1
        return True

    shutdown = Shutdown()
    seat = ZoneSeat(_Session(live), KEYS, mid="a", zone=ZONE, can_lead=can_lead, shutdown=shutdown)
    try:
        assert wait_until(lambda: seat.leader() == "b", 10.0), "the first whole view names b the leader"
        assert wait_until(lambda: live.gets >= 5, 10.0), "the timed-out reads"
        seen = checks
        assert wait_until(lambda: checks >= seen + 2, 5.0), "the seat's loop to take what the reads gave"
        assert (seat.role, seat.leader()) == ("standby", "b"), "claimed from a read the router did not answer"
        live.moved_on.set()
        assert wait_until(lambda: seat.role == "leader", 10.0), "the whole view without b: a claims"
        assert (seat.election.term, seat.leader()) == (3, "a")
    finally:
        shutdown.set()
        seat.close()


def test_a_person_who_walks_into_a_zone_while_its_leader_is_gone_keeps_the_neighbours_id() -> None:
    """A 10 m room cut along x = 5 m; the west zone's leader is gone (killed, its lease not yet over), its standby
    fuses the frames. A person walks from the east zone into the west's: the east publishes them as ``east-1``
    until they are a band past the border. The standby names its track of them after the east's, as a leader
    would, so when it takes over it publishes them under ``east-1``, not under an id of its own."""
    band = 1.0
    cams = [Cam("c1", 0.2, 0.2), Cam("c2", 9.8, 0.2, yaw=3.1), Cam("c3", 9.8, 9.8, yaw=-2.4), Cam("c4", 0.2, 9.8)]
    infos = [info_for(c) for c in cams]
    standby = Fusion(make_config("west-b"))
    west = ZoneOwnership(Area.of(rectangle(0.0, 0.0, 5.0, 10.0)), band)
    east = ZoneOwnership(Area.of(rectangle(5.0, 0.0, 10.0, 10.0)), band)
    rng = np.random.default_rng(1)
    ids = []
    for tick in range(1, 90):
        t = tick / 10.0
        x = 9.0 - 1.0 * t
        t_ns = T0_NS + int(t * 1e9)
        frames = [features_for(c, [Person(x, 5.0)], cams, t_ns, tick, rng) for c in cams]
        standby.absorb(Batch(features=frames, infos=infos))
        standby.step(t_ns - 100_000_000)
        theirs = east.select([published("east-1", x, vx=-1.0, t_ns=t_ns, mid="east")], t_ns)
        west.heard(TrackSet(manager_id="east", seq=tick, stamp_ns=t_ns, tracks=theirs), t_ns)
        standby_names(standby, None, west, t_ns)
        if x < 5.0 - band - 0.5:  # the east has let the person go: what the standby would publish on taking over
            ids.append({tr.track_id for tr in standby.published_tracks()})
    assert ids and all(got == {"east-1"} for got in ids), ids
