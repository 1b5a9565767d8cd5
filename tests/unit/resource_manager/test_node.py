"""The manager's shell, without a zenoh session (its loopback runs are tests/integration's): a manager's seat in
its zone reads the zone's seats whole, and a read the router did not answer is not a whole view."""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from common.keys import Keys
from common.session import Shutdown, wait_until
from resource_manager.node import ZoneSeat

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
