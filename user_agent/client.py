"""Python API of a user agent: read tracks, sensors and plans of any site; ask for PTZ views.

A :class:`AgentClient` is a zenoh client of the site's router (or uses a
session you pass in). It keeps the newest TrackSet of every manager, the
newest status of every sensor and manager, view plans, pair choices and every
sensor's SensorInfo (an AdvancedSubscriber: the nodes' publisher caches give a
late joiner the current ones), from subscriptions whose zenoh callbacks only
enqueue bytes (common.transport); a pump thread decodes them and calls your
subscribers. Queries (track state, history, PTZ allocation) are plain zenoh
``get`` calls on the keys of :mod:`common.keys`.

PTZ views are leases: :meth:`AgentClient.request_view` holds a camera for the
lease the manager grants (``PtzReply.lease_s``), :meth:`AgentClient.keep_views`
renews what this client holds, and every hold ends when the client's
liveliness token goes (:meth:`close`, exit, crash).

Example::

    from user_agent.client import AgentClient
    with AgentClient(connect=["tcp/192.168.1.10:7447"]) as agent:
        for track in agent.tracks(timeout_s=5):
            print(track.track_id, track.x_m, track.y_m)
        path = agent.history("mgr1-3", seconds=30)
"""

from __future__ import annotations

import contextlib
import itertools
import logging
import os
import threading
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any, TypeVar

from common.codec import decode, encode
from common.errors import SchemaError, SessionError
from common.keys import DEFAULT_PREFIX, Keys, validate_id
from common.schema import (
    ManagerStatus,
    NodeStatus,
    PairChoice,
    PtzReply,
    PtzRequest,
    SensorInfo,
    Track,
    TrackSet,
    ViewPlan,
)
from common.session import MSGPACK, SessionSettings, open_session
from common.transport import Inbox, KeyedInbox

__all__ = ["AgentClient", "ManagerView", "SensorView", "Subscription", "merge_history", "merge_tracks"]

logger = logging.getLogger(__name__)

T = TypeVar("T")


@dataclass(frozen=True, slots=True)
class SensorView:
    """What the network says about one sensor."""

    sensor_id: str
    alive: bool
    """Its liveliness token is present."""
    info: SensorInfo | None
    status: NodeStatus | None

    @property
    def clock_offset_ns(self) -> int:
        """The node's NTP clock offset (status first, else info; 0 when unknown)."""
        if self.status is not None:
            return self.status.clock_offset_ns
        return self.info.clock_offset_ns if self.info is not None else 0


@dataclass(frozen=True, slots=True)
class ManagerView:
    manager_id: str
    alive: bool
    status: ManagerStatus | None


ACCEPTED_REPLIES = 2
"""A liveliness query for the agent's own token answered by its session and by the router: the router took it."""
MAX_KEPT = 256
"""Most senders an agent keeps the latest message of, per kind: a flood of fresh ids cannot grow its memory (the
least recently heard one goes)."""


def merge_tracks(sets: Iterable[TrackSet]) -> list[Track]:
    """The tracks of several managers' TrackSets, one per id (the newest state), by id."""
    out: dict[str, Track] = {}
    for ts in sets:
        for t in ts.tracks:
            old = out.get(t.track_id)
            if old is None or t.stamp_ns > old.stamp_ns:
                out[t.track_id] = t
    return sorted(out.values(), key=lambda t: t.track_id)


def merge_history(replies: Iterable[Track]) -> list[Track]:
    """A track's path from every manager that answered (each its own part: the zones it crossed, a standby's copy
    of its leader's), oldest first, one state per instant."""
    by_stamp: dict[int, Track] = {}
    for t in replies:
        by_stamp.setdefault(t.stamp_ns, t)
    return [by_stamp[k] for k in sorted(by_stamp)]


def _keep(table: dict[str, Any], key: str, value: Any) -> None:
    """``table[key] = value``, most recent last; beyond MAX_KEPT keys the least recently heard goes."""
    table.pop(key, None)
    if len(table) >= MAX_KEPT:
        del table[next(iter(table))]
    table[key] = value


class Subscription:
    """A TrackSet callback; :meth:`close` stops it."""

    def __init__(self, owner: AgentClient, callback: Callable[[TrackSet], None]) -> None:
        self._owner = owner
        self.callback = callback

    def close(self) -> None:
        self._owner._unsubscribe(self)

    def __enter__(self) -> Subscription:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class AgentClient:
    """A user agent's connection to a site.

    Args:
        session: an open zenoh session to use (not closed by the client); if
            None, one is opened from ``settings`` or ``connect``.
        settings: how to join (mode, endpoints, TLS config file, user/password).
        connect: shorthand for ``SessionSettings(connect=connect)``.
        prefix: the site's key prefix.
        agent_id: announced as a liveliness token ``{root}/agent/{id}`` and sent
            with PTZ requests (default ``agent-<pid>``).
        sensors: follow only these sensors' statuses and SensorInfo (None: every sensor). An agent that knows
            its site's sensors (the demo) then receives nothing of what others publish under other ids.
    """

    def __init__(
        self,
        session: Any | None = None,
        *,
        settings: SessionSettings | None = None,
        connect: list[str] | None = None,
        prefix: str = DEFAULT_PREFIX,
        agent_id: str | None = None,
        sensors: Sequence[str] | None = None,
    ) -> None:
        self.keys = Keys(prefix)
        self.agent_id = validate_id(agent_id or f"agent-{os.getpid()}", "agent id")
        self._stack = contextlib.ExitStack()
        if session is None:
            s = settings or SessionSettings(connect=list(connect or []))
            session = self._stack.enter_context(open_session(s))
        self.session = session
        self._lock = threading.Lock()
        self._changed = threading.Condition(self._lock)
        self._tracksets: dict[str, TrackSet] = {}
        self._heard: dict[str, float] = {}
        """Manager id -> monotonic time its last TrackSet arrived."""
        self._node_status: dict[str, NodeStatus] = {}
        self._mgr_status: dict[str, ManagerStatus] = {}
        self._plans: dict[str, ViewPlan] = {}
        self._pairs: dict[str, PairChoice] = {}
        self._infos: dict[str, SensorInfo] = {}
        self._held: dict[str, tuple[str | None, int, float]] = {}
        """Track id -> (manager id given, priority, monotonic time to renew) of the views this client holds."""
        self._subs: list[Subscription] = []
        self._seq = itertools.count()
        self._stop = threading.Event()
        try:
            self._token = session.liveliness().declare_token(self.keys.agent(self.agent_id))
            self._in_tracks = Inbox(session, self.keys.tracks(), TrackSet, capacity=256)
            k = self.keys
            status_keys = [k.all_sensor_status] if sensors is None else [k.sensor_status(s) for s in sensors]
            info_keys = [k.all_sensor_info] if sensors is None else [k.sensor_info(s) for s in sensors]
            self._in_status = KeyedInbox(session, status_keys, NodeStatus, capacity=4)
            self._in_mgr = Inbox(session, self.keys.all_manager_status, ManagerStatus, capacity=64)
            self._in_plans = Inbox(session, self.keys.all_plans, ViewPlan, capacity=64)
            self._in_pairs = Inbox(session, self.keys.all_pairs, PairChoice, capacity=64)
            self._in_infos = KeyedInbox(session, info_keys, SensorInfo, capacity=2, advanced=True)
        except Exception:
            self._stack.close()
            raise
        self._thread = threading.Thread(target=self._pump, name="agent-pump", daemon=True)
        self._thread.start()

    def token_accepted(self, timeout_s: float = 3.0) -> bool:
        """Whether the router took this agent's liveliness token (a secure site's rules allow only the id of the
        agent's certificate; a denied token is dropped silently, and so are this agent's PTZ requests).

        The agent's own session answers a liveliness query for its token locally; the router answers too only
        when it has the token. So two answers: accepted; one: refused (or no router to ask). A token just declared
        may not have reached the router yet, and a busy router answers late: asked again until ``timeout_s``.
        """
        key = self.keys.agent(self.agent_id)
        deadline = time.monotonic() + timeout_s
        while True:
            left = deadline - time.monotonic()
            try:
                replies = [
                    r for r in self.session.liveliness().get(key, timeout=min(1.0, max(left, 0.1))) if r.ok is not None
                ]
            except Exception as err:  # session closing
                logger.debug("liveliness query %s: %s", key, err)
                return True
            if len(replies) >= ACCEPTED_REPLIES:
                return True
            if time.monotonic() >= deadline:
                return False
            time.sleep(0.1)

    # -- lifecycle ----------------------------------------------------------
    def close(self) -> None:
        """Stop the pump, undeclare everything, close the session if we opened it."""
        if self._stop.is_set():
            return
        self._stop.set()
        self._thread.join(timeout=5)
        for inbox in (self._in_tracks, self._in_status, self._in_mgr, self._in_plans, self._in_pairs):
            inbox.close()
        self._in_infos.close()
        with contextlib.suppress(Exception):
            self._token.undeclare()
        self._stack.close()

    def __enter__(self) -> AgentClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- background ---------------------------------------------------------
    def _pump(self) -> None:
        while not self._stop.is_set():
            got = self._in_tracks.get(timeout_s=0.05)
            sets = [got] if got is not None else []
            sets += self._in_tracks.drain()
            with self._lock:
                for r in sets:
                    old = self._tracksets.get(r.msg.manager_id)
                    if old is None or r.msg.stamp_ns >= old.stamp_ns or r.msg.seq < old.seq:
                        _keep(self._tracksets, r.msg.manager_id, r.msg)
                    _keep(self._heard, r.msg.manager_id, time.monotonic())
                self._take_statuses()
                subs = list(self._subs)
                self._changed.notify_all()
            for r in sets:
                for sub in subs:
                    try:
                        sub.callback(r.msg)
                    except Exception:
                        logger.exception("track subscriber callback failed")

    def _take_statuses(self) -> None:
        """Keep what arrived besides tracks: statuses, plans, pairs, SensorInfo (the caller holds the lock).

        A status or SensorInfo counts only under its own sender's key."""
        for key, data in self._in_status.drain_raw():
            st = self._in_status.decode(key, data)
            if st is not None and key == self.keys.sensor_status(st.sensor_id):
                _keep(self._node_status, st.sensor_id, st)
        for m in self._in_mgr.drain():
            if m.key == self.keys.manager_status(m.msg.manager_id):
                _keep(self._mgr_status, m.msg.manager_id, m.msg)
        for p in self._in_plans.drain():
            _keep(self._plans, p.msg.sensor_id, p.msg)
        for c in self._in_pairs.drain():
            _keep(self._pairs, c.msg.manager_id, c.msg)
        for key, data in self._in_infos.drain_raw():
            info = self._in_infos.decode(key, data)
            if info is not None and key == self.keys.sensor_info(info.sensor_id):
                _keep(self._infos, info.sensor_id, info)

    def _unsubscribe(self, sub: Subscription) -> None:
        with self._lock:
            if sub in self._subs:
                self._subs.remove(sub)

    def _wait(self, pred: Callable[[], bool], timeout_s: float) -> bool:
        deadline = time.monotonic() + timeout_s
        with self._changed:
            while not pred():
                left = deadline - time.monotonic()
                if left <= 0:
                    return False
                self._changed.wait(min(left, 0.1))
            return True

    def _query(self, selector: Any, msg_type: type[T], timeout_s: float, payload: bytes | None = None) -> list[T]:
        import zenoh

        out: list[T] = []
        try:
            # No consolidation: a history answer is many replies on the same key, all wanted.
            replies = self.session.get(
                selector,
                timeout=timeout_s,
                payload=payload,
                encoding=MSGPACK if payload else None,
                consolidation=zenoh.ConsolidationMode.NONE,
            )
        except Exception as err:
            raise SessionError(f"query {selector} failed: {err}") from err
        for reply in replies:
            if reply.ok is None:
                logger.debug("query %s: error reply %s", selector, reply.err.payload.to_string())
                continue
            try:
                out.append(decode(reply.ok.payload.to_bytes(), msg_type))
            except SchemaError as err:
                logger.warning("query %s: bad reply dropped: %s", selector, err)
        return out

    # -- tracks -------------------------------------------------------------
    def track_sets(self, timeout_s: float = 0.0, stale_s: float = 2.0) -> dict[str, TrackSet]:
        """The newest TrackSet of every manager heard from in the last ``stale_s`` seconds.

        Waits up to ``timeout_s`` for a first one. A manager that stopped
        publishing (crashed, partitioned) drops out after ``stale_s``, so its
        tracks are not shown as current.
        """
        self._wait(lambda: bool(self._tracksets), timeout_s)
        now = time.monotonic()
        with self._lock:
            return {m: ts for m, ts in self._tracksets.items() if now - self._heard.get(m, 0.0) <= stale_s}

    def tracks(self, timeout_s: float = 2.0, stale_s: float = 2.0) -> list[Track]:
        """Every current track of every live manager, by track id: one per person site-wide (zone managers each
        publish the people they own; an id two of them published at a handover is shown once, its newest state)."""
        return merge_tracks(self.track_sets(timeout_s, stale_s).values())

    def _publisher_of(self, track_id: str) -> str:
        """The manager publishing ``track_id`` now (a zone's standby that took over publishes its leader's ids),
        else the one its id names (``{manager_id}-{n}``)."""
        for mid, ts in self.track_sets().items():
            if any(t.track_id == track_id for t in ts.tracks):
                return mid
        return track_id.rsplit("-", 1)[0]

    def subscribe(self, callback: Callable[[TrackSet], None]) -> Subscription:
        """Call ``callback(trackset)`` for every TrackSet (on the client's pump thread; keep it short)."""
        sub = Subscription(self, callback)
        with self._lock:
            self._subs.append(sub)
        return sub

    def latest(self, track_id: str, timeout_s: float = 2.0) -> Track | None:
        """Query the manager for a track's latest state (None if no manager knows it)."""
        replies = self._query(self.keys.track(track_id), Track, timeout_s)
        return max(replies, key=lambda t: t.stamp_ns) if replies else None

    def history(self, track_id: str, seconds: float, timeout_s: float = 3.0) -> list[Track]:
        """A track's path over the last ``seconds``, oldest first (``get track/{id}?history=S``)."""
        import zenoh

        if not seconds > 0:
            raise SessionError(f"history seconds must be > 0, got {seconds}")
        sel = zenoh.Selector(self.keys.track(track_id), {"history": f"{seconds:g}"})
        return merge_history(self._query(sel, Track, timeout_s))

    # -- sensors, managers, plans --------------------------------------------
    def _alive(self, key_expr: str, timeout_s: float) -> set[str]:
        alive: set[str] = set()
        for reply in self.session.liveliness().get(key_expr, timeout=timeout_s):
            if reply.ok is not None:
                with contextlib.suppress(Exception):
                    alive.add(self.keys.parse(str(reply.ok.key_expr)).ident)
        return alive

    def sensors(self, timeout_s: float = 1.0) -> list[SensorView]:
        """Every sensor seen (alive, or with a status/info): info, status and clock offset.

        SensorInfo comes from the nodes' publisher caches (AdvancedSubscriber history); a sensor alive without
        one (a third-party node with a plain queryable) is asked once with a ``get``.
        """
        alive = self._alive(self.keys.all_sensors, timeout_s)
        with self._lock:
            status = dict(self._node_status)
            infos = dict(self._infos)
        missing = alive - set(infos)
        if missing:
            for i in self._query(self.keys.all_sensor_info, SensorInfo, timeout_s):
                infos.setdefault(i.sensor_id, i)
        ids = sorted(alive | set(infos) | set(status))
        return [SensorView(s, s in alive, infos.get(s), status.get(s)) for s in ids]

    def managers(self, timeout_s: float = 1.0) -> list[ManagerView]:
        alive = self._alive(self.keys.all_managers, timeout_s)
        with self._lock:
            status = dict(self._mgr_status)
        return [ManagerView(m, m in alive, status.get(m)) for m in sorted(alive | set(status))]

    def plans(self) -> list[ViewPlan]:
        """The newest view plan for every mobile camera."""
        with self._lock:
            return [self._plans[k] for k in sorted(self._plans)]

    def pairs(self) -> dict[str, PairChoice]:
        """The newest pair choice of every manager."""
        with self._lock:
            return dict(self._pairs)

    # -- PTZ views -----------------------------------------------------------
    def _ptz(
        self, action: str, track_id: str, priority: int, manager_id: str | None, timeout_s: float, *, lease_s: float
    ) -> PtzReply:
        validate_id(track_id, "track id")
        mid = manager_id or self._publisher_of(track_id)
        req = PtzRequest(
            agent_id=self.agent_id,
            seq=next(self._seq),
            stamp_ns=time.time_ns(),
            action=action,  # type: ignore[arg-type]
            track_id=track_id,
            priority=priority,
            lease_s=lease_s,
        )
        key = self.keys.ptz_request(mid, self.agent_id)
        replies = self._query(key, PtzReply, timeout_s, payload=encode(req))
        if not replies:
            raise SessionError(
                f"no PTZ reply from manager {mid!r} within {timeout_s:g} s (is it running? on a secure site, "
                f"is {self.agent_id!r} this agent's certificate id?)"
            )
        return replies[0]

    def request_view(
        self,
        track_id: str,
        priority: int = 0,
        manager_id: str | None = None,
        timeout_s: float = 2.0,
        lease_s: float = 0.0,
    ) -> PtzReply:
        """Ask the manager for a PTZ camera to look at a track.

        The manager is the one publishing the track now, or the one named in the track id (``{manager_id}-{n}``),
        unless ``manager_id`` is given. The reply names the camera, or why none.
        The hold lasts ``reply.lease_s`` (``lease_s`` if shorter than the manager's)
        unless renewed by asking again (:meth:`keep_views` does), and ends at once
        when this client closes.

        Raises:
            SessionError: if no manager answers.
        """
        reply = self._ptz("acquire", track_id, priority, manager_id, timeout_s, lease_s=lease_s)
        with self._lock:
            if reply.ok:
                self._held[track_id] = (manager_id, priority, time.monotonic() + reply.lease_s / 3.0)
            else:
                self._held.pop(track_id, None)
        return reply

    def release_view(self, track_id: str, manager_id: str | None = None, timeout_s: float = 2.0) -> PtzReply:
        """Give a PTZ view back."""
        with self._lock:
            self._held.pop(track_id, None)
        return self._ptz("release", track_id, 0, manager_id, timeout_s, lease_s=0.0)

    def keep_views(self) -> list[PtzReply]:
        """Renew the views this client holds whose lease is a third gone; returns the replies (a lost view's too)."""
        now = time.monotonic()
        with self._lock:
            due = [(tid, mid, prio) for tid, (mid, prio, at) in self._held.items() if now >= at]
        return [self.request_view(tid, prio, mid) for tid, mid, prio in due]

    def release_all(self) -> None:
        """Release every view this client holds (best effort: the holds end with the client anyway)."""
        with self._lock:
            held = [(tid, mid) for tid, (mid, _, _) in self._held.items()]
        for tid, mid in held:
            try:
                self.release_view(tid, mid)
            except SessionError as err:
                logger.warning("releasing the view of %s: %s", tid, err)
