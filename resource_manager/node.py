"""The resource manager process: zenoh in, :class:`~resource_manager.fusion.Fusion` per tick, zenoh out.

Subscriptions are made per listed sensor (``[manager] sensors``, or its
site's): the router forwards nothing else, so a flood under other ids costs
this process nothing but a count (a census on ``sensor/**`` that pauses itself
when flooded; a manager of one zone among several keeps none: the other zones'
cameras are not strangers). Each listed sensor's Features, SensorInfo (an AdvancedSubscriber:
the publisher's cache for late joiners) and PTZ state wait in a bounded buffer
of their own and are decoded on the tick thread, never on zenoh's; a payload that names
another sensor than its key, and Features stamped off the clock by more than
``max_skew_s``, are refused and counted (:mod:`resource_manager.ingest.gate`).
SensorInfo is re-read from each sensor's queryable on a period and when its
liveliness token comes back (:mod:`resource_manager.ingest.infos`).

The tick thread sleeps until a Features message arrives or a sensor's deadline
passes, then fuses the instant the sensors' watermark allows
(:mod:`resource_manager.ingest.schedule`; at most ``rate_hz``), and publishes
the TrackSet on ``tracks``, each track on ``track/{id}``, the pair
choices on ``manager/{id}/pairs``, view plans on ``plan/{sensor}``, PTZ commands
on ``sensor/{id}/ptz``; ManagerStatus at 1 Hz. Queryables answer ``track/*``
(latest state, or the path with ``?history=SECONDS``) and PTZ requests on
``manager/{id}/ptz/{agent}``: queued, applied and answered in the tick. Agents'
liveliness tokens end their PTZ holds when they go. The track history is
logged to disk and reloaded at start (:mod:`resource_manager.serve.history`).

With ``[manager] zone``, the manager holds a seat in its zone (:class:`ZoneSeat`,
:mod:`resource_manager.serve.election`): while another manager leads the zone it stands by, fusing the same frames
and publishing only its status, its tracks named after the leader's TrackSets
(:mod:`resource_manager.serve.adopt`), whose states it keeps as history; it answers no track or PTZ query. When it
leads, it publishes as above.

With a zone floor (``[manager] zone_polygon``, which ``--site`` sets from the site's ``[[zones]]``) a leader publishes
only the tracks it owns (:mod:`resource_manager.serve.zones`): it hears the other managers' TrackSets on ``tracks``,
and names the tracks it does not publish after its neighbours' tracks of the same people, so that a person walking
in from a neighbouring zone keeps the id. Its standby names them so too (:func:`standby_names`): a person who walks
in while the leader is gone keeps the id when the standby takes over.
"""

from __future__ import annotations

import itertools
import logging
import queue
import threading
import time
from collections import deque
from collections.abc import Callable
from pathlib import Path
from typing import Any

import msgspec

from common.area import Area, AreaSpec
from common.clock import NtpClock
from common.codec import MAX_PAYLOAD_BYTES, decode, encode
from common.errors import ConfigError, SchemaError
from common.keys import Keys
from common.memory import Trimmer, pin_mmap_threshold
from common.ratelog import SenderLog
from common.schema import (
    MAX_SENSORS,
    MAX_TEXT_LEN,
    Features,
    Latency,
    PtzReply,
    PtzRequest,
    PtzState,
    SensorInfo,
    Track,
    TrackSet,
)
from common.session import MSGPACK, Shutdown, install_signal_handlers, open_session, refuse_second
from common.transport import Inbox, KeyCensus, KeyedInbox, TypedPublisher
from resource_manager.config import ManagerConfig
from resource_manager.fusion import Batch, Fusion, TickResult
from resource_manager.ingest.gate import SenderGate, sender_in_key
from resource_manager.ingest.infos import InfoGate
from resource_manager.poses.agreement import Agreement
from resource_manager.serve.election import Election, Seat
from resource_manager.serve.history import IdAllocator, TrackLog, TrackStore, read_segments
from resource_manager.serve.ptz import Assignment, PtzAnswer, PtzAsk
from resource_manager.serve.status import InboxCounts, manager_status
from resource_manager.serve.zones import ZoneOwnership

__all__ = ["ManagerNode", "run"]

MAX_SLEEP_S = 0.1
"""Longest the tick thread sleeps with nothing arriving and no deadline due (liveliness, PTZ requests and the
census are looked at on each wake)."""

logger = logging.getLogger(__name__)

FRAMES_PER_SENSOR = 16
"""Features waiting per sensor between ticks (1.6 ticks' worth at 100 Hz frames); a flood on one sensor's key
pushes out (and counts) only that sensor's frames."""
BUDGET_FPS = 30.0
"""The frame rate ``[manager] sensor_bytes_per_s`` is sized for: a frame larger than the budget's 1/30 is large."""
INFOS_PER_SENSOR = 4
"""SensorInfo messages waiting per sensor between ticks (each only a reason to read it again)."""
PTZ_STATES_PER_SENSOR = 8
"""PTZ states waiting per sensor between ticks."""
MAX_PENDING_PTZ = 256
"""PTZ requests waiting for the next tick; beyond them a request is answered "busy" at once."""

MAX_HISTORY_QUERY_S = 1e7
"""The longest ``?history=SECONDS`` a track query may ask for (~116 days: anything longer is a typo)."""

SEAT_RESYNC_S = 2.0
"""A zone's seats are read whole (liveliness ``get``) this often, besides the subscriber's changes: a view that
missed a change (a reconnection) is right again within this long."""
SEAT_RETRY_S = 0.1
"""A read of the zone's seats that came back incomplete is asked again after this pause."""
FRESH_FRAMES_S = 1.0
"""A standby may claim its zone only while its sensors' frames reach it: one arrived within this long."""
LEADER_SETS = 64
"""Other managers' TrackSets waiting for the next tick (a standby's leader's, a zone manager's neighbours')."""


class ZoneSeat:
    """This manager's seat in its zone: the token its role names, kept from the zone's seats by
    :class:`~resource_manager.serve.election.Election` on a thread of its own.

    The seats come from a liveliness ``get`` on a second thread, every :data:`SEAT_RESYNC_S` and at once when the
    liveliness subscriber hears a seat go (the whole view: a change missed across a reconnection is righted too),
    and from the subscriber's new seats, all queued in arrival order: a slow ``get`` never delays the decisions. A
    read the router did not answer in time is read again, not taken as a whole view.

    Args:
        can_lead: whether the manager's sensors reach it now (a standby cut off from them never claims).
    """

    def __init__(
        self, session: Any, keys: Keys, *, mid: str, zone: str, can_lead: Callable[[], bool], shutdown: Shutdown
    ) -> None:
        import zenoh

        self.put_kind = zenoh.SampleKind.PUT
        self.session, self.keys, self.mid, self.zone = session, keys, mid, zone
        self.can_lead = can_lead
        self.shutdown = shutdown
        self.election = Election(mid)
        self.lock = threading.Lock()
        self.events: deque[tuple[Seat, bool, int] | tuple[list[Seat], int, int]] = deque(maxlen=4 * MAX_SENSORS)
        """Seat changes (seat, alive, number) and whole views (seats, the number of the read, the number of the last
        change before it began) in arrival order."""
        self.heard = itertools.count(1)
        self.last_heard = 0
        self.wake = threading.Event()
        self.read_now = threading.Event()
        self.read_now.set()  # the first whole view at once: no claim is made before it
        self.reads_asked = 0
        self.held_until = 1
        """The leader holds its tracks back until a whole view read after this request number has been taken
        (none yet at start; and again after its frames stopped: when they come back from a healed link, it hears
        the newer leader before it publishes)."""
        self.token = session.liveliness().declare_token(keys.zone_standby(mid, zone))
        self.sub = session.liveliness().declare_subscriber(keys.zone_seats(zone), self._on_seat)
        self.threads = [
            threading.Thread(target=self._loop, name="zone-seat", daemon=True),
            threading.Thread(target=self._read_loop, name="zone-seats-read", daemon=True),
        ]
        for t in self.threads:
            t.start()

    @property
    def role(self) -> str:
        return self.election.role

    @property
    def leading(self) -> bool:
        """Whether the manager publishes now: it leads, and has read the zone's seats since its frames came."""
        return self.election.role == "leader" and self.held_until == 0

    def leader(self) -> str:
        with self.lock:
            return self.election.leader() or ""

    def _seat(self, key: str) -> Seat | None:
        try:
            p = self.keys.parse(key)
        except ConfigError:
            return None
        if p.parent != self.zone or p.kind not in ("zone_leader", "zone_standby"):
            return None
        return Seat(p.ident, "leader" if p.kind == "zone_leader" else "standby", p.term)

    def _on_seat(self, sample: Any) -> None:
        if sample.kind != self.put_kind:
            # A token gone: read the seats whole before believing it. zenoh 1.10 sometimes names another token in
            # the DELETE it sends when a client dies (seen here: the standby's own seat, for its killed leader's),
            # so what went is asked of the router, which answers at once.
            self.read_now.set()
            return
        seat = self._seat(str(sample.key_expr))
        if seat is not None:
            with self.lock:
                self.last_heard = next(self.heard)
                self.events.append((seat, True, self.last_heard))
            self.wake.set()

    def _read_loop(self) -> None:
        """Read the zone's seats whole every :data:`SEAT_RESYNC_S`, or at once when asked."""
        while not self.shutdown.is_set():
            self.read_now.wait(SEAT_RESYNC_S)
            self.read_now.clear()
            number = self.reads_asked
            with self.lock:
                before = self.last_heard
            try:
                replies = list(self.session.liveliness().get(self.keys.zone_seats(self.zone), timeout=1.0))
            except Exception as err:  # session closing
                logger.debug("zone seats query: %s", err)
                continue
            if any(r.ok is None for r in replies):
                # A reply that errs (the router's answer timed out: a busy host, a link coming back) leaves only the
                # seats this session holds itself: as a whole view it would say every other seat went, and a
                # standby would claim over a leader that is there. Read again instead.
                logger.debug("zone seats query of %s incomplete: read again", self.zone)
                self.shutdown.sleep(SEAT_RETRY_S)
                self.read_now.set()
                continue
            seats = [s for r in replies if (s := self._seat(str(r.ok.key_expr))) is not None]
            self.events.append((seats, number, before))
            self.wake.set()

    def _loop(self) -> None:
        while not self.shutdown.is_set():
            self.wake.wait(0.1)
            self.wake.clear()
            can = self.can_lead()
            if not can and self.held_until == 0:
                self.held_until = self.reads_asked + 1  # frames stopped: hold until a read after they are back
            if can and self.held_until > self.reads_asked:
                self.reads_asked += 1
                self.read_now.set()
            read = self._take_events()
            with self.lock:
                changed = self.election.decide(can, time.monotonic())
                role, term = self.election.role, self.election.term
            if changed:
                self._take_seat(role, term)
            if can and 0 < self.held_until <= read:
                self.held_until = 0

    def _take_events(self) -> int:
        """Apply what arrived; returns the number of the newest whole view taken (0: none)."""
        read = 0
        with self.lock:
            while self.events:
                what, flag, number = self.events.popleft()
                if isinstance(what, Seat):
                    self.election.saw(what, bool(flag), number)
                else:
                    self.election.resync(what, number)
                    read = max(read, int(flag))
        return read

    def _take_seat(self, role: str, term: int) -> None:
        """Declare the new role's token before the old one goes: the zone never sees this manager seatless."""
        key = (
            self.keys.zone_leader(self.mid, self.zone, term)
            if role == "leader"
            else self.keys.zone_standby(self.mid, self.zone)
        )
        old, self.token = self.token, self.session.liveliness().declare_token(key)
        logger.warning(
            "manager %s is now the %s of zone %s%s",
            self.mid,
            role,
            self.zone,
            f" (term {term})" if role == "leader" else f" (leader: {self.leader() or 'none'})",
        )
        try:
            old.undeclare()
        except Exception as err:
            logger.debug("undeclare seat: %s", err)

    def close(self) -> None:
        self.wake.set()
        self.read_now.set()
        for t in self.threads:
            t.join(timeout=2.0)
        for ent in (self.sub, self.token):
            try:
                ent.undeclare()
            except Exception as err:  # already closed with the session
                logger.debug("undeclare: %s", err)


class ManagerNode:
    """Everything one manager process holds; ``loop()`` runs until ``shutdown``."""

    followed: str | None = None
    """The leader whose tracks this manager, standing by, names its own after (None while it leads)."""

    def __init__(self, session: Any, cfg: ManagerConfig, clock: NtpClock, shutdown: Shutdown) -> None:
        import zenoh

        self._zenoh = zenoh
        self.session = session
        self.cfg = cfg
        self.clock = clock
        self.shutdown = shutdown
        self.keys = Keys(cfg.manager.prefix)
        self.mid = cfg.manager.id
        m = cfg.manager
        self.gate = SenderGate.of(m.sensors, int(m.max_skew_s * 1e9), int(m.max_lead_s * 1e9))
        self.info_gate = InfoGate(int(cfg.manager.info_refresh_s * 1e9))
        state = Path(cfg.manager.state_dir)
        self.ids = IdAllocator(state, self.mid)
        self.store = self._reload(state)
        self.log = TrackLog(state / "tracks", cfg.manager.segment_s, cfg.manager.retain_s)
        self.fusion = Fusion(cfg, new_id=self.ids)
        self.lock = threading.Lock()
        self.live_ids: set[str] = set()
        self.presence: deque[tuple[str, bool]] = deque()
        self.agent_presence: deque[tuple[str, bool]] = deque()
        self.fetched_infos: deque[tuple[str, SensorInfo]] = deque()
        self.fetch_queue: queue.Queue[str | None] = queue.Queue()
        self.ptz_asks: deque[PtzAsk] = deque()
        self.ptz_queries: dict[int, Any] = {}
        self.ptz_tokens = itertools.count(1)
        self.query_errors = 0
        self.sender_log = SenderLog(logger)
        """Lines a sender can provoke (PTZ requests and holds ended, per agent; track-log errors) are written once a
        second per sender, with a count: a flood of requests writes no flood of lines."""
        k = self.keys
        self.sensor_head = f"{k.root}/sensor/"
        listed = self.gate.expected
        self.census: KeyCensus | None = None
        self.wake = threading.Event()
        """Set by each arriving Features message (and PTZ request): the tick thread looks at once."""
        self.latencies: deque[Latency] = deque(maxlen=4096)
        """Capture -> publish split of each TrackSet published since the last status."""
        self.features, self.infos, self.ptz_states = self._inboxes(session, listed)
        # The census of unlisted senders hears every sample on ``sensor/**``. A manager of one zone among several
        # shares the router with the other zones' cameras: they are no strangers (counted, they would be reported as
        # impostors), and hearing their every frame is work for nothing, so it counts none.
        if not self.gate.any_sensor and not self.cfg.manager.zone_polygon:
            self.census = KeyCensus(session, f"{k.root}/sensor/**", self.sensor_head, frozenset(listed))
        self._declare(session)
        self.fetcher = threading.Thread(target=self._fetch_loop, name="sensor-info-fetch", daemon=True)
        self.fetcher.start()
        self.tick_times: list[tuple[float, float]] = []  # (wall clock, fusing thread's CPU) ms per tick
        self.status_seq = 0
        self.agreement = Agreement()
        self.ticks = 0
        self.last_frame = 0.0  # when (monotonic) the latest Features reached the fusion
        self.ownership: ZoneOwnership | None = None
        self.leader_sets, self.seat = self._zone(session)
        # Last: the token says the manager is ready (its queryables answer).
        self.token = session.liveliness().declare_token(k.manager(self.mid))

    def _declare(self, session: Any) -> None:
        """The manager's publishers, liveliness subscribers and queryables."""
        k = self.keys
        self.pub_tracks = TypedPublisher(session, k.tracks(), reliable_block=True)
        self.pub_pairs = TypedPublisher(session, k.manager_pairs(self.mid))
        self.pub_status = TypedPublisher(session, k.manager_status(self.mid), reliable_block=True)
        self.live_sub = session.liveliness().declare_subscriber(k.all_sensors, self._on_liveliness, history=True)
        self.agent_sub = session.liveliness().declare_subscriber(k.all_agents, self._on_agent_liveliness)
        self.q_tracks = session.declare_queryable(k.all_tracks, self._on_track_query)
        self.q_ptz = session.declare_queryable(k.ptz_requests(self.mid), self._on_ptz_query)
        self.q_ptz_old = session.declare_queryable(k.manager_ptz(self.mid), self._on_old_ptz_query)

    def _zone(self, session: Any) -> tuple[Inbox[TrackSet] | None, ZoneSeat | None]:
        """With ``[manager] zone``: its seat in the zone, and the leader's TrackSets a standby hears (the ids to
        adopt, the history to serve once it leads)."""
        zone = self.cfg.manager.zone
        if not zone:
            return None, None
        if self.cfg.manager.zone_polygon:
            area = Area.of(AreaSpec(polygon=self.cfg.manager.zone_polygon), "manager.zone_polygon")
            self.ownership = ZoneOwnership(area, self.cfg.manager.zone_band_m)
        sets = Inbox(session, self.keys.tracks(), TrackSet, capacity=LEADER_SETS)
        seat = ZoneSeat(session, self.keys, mid=self.mid, zone=zone, can_lead=self._can_lead, shutdown=self.shutdown)
        return sets, seat

    @property
    def leading(self) -> bool:
        """Whether this manager publishes: always without a zone, else while it leads its zone."""
        return self.seat is None or self.seat.leading

    def _can_lead(self) -> bool:
        return time.monotonic() - self.last_frame < FRESH_FRAMES_S

    def _reload(self, state: Path) -> TrackStore:
        """The in-memory track history, reloaded from the log on disk."""
        m = self.cfg.manager
        store = TrackStore(m.history_s, m.history_hz, m.history_max_mb)
        reloaded = read_segments(state / "tracks", self.clock.now_ns() - int(m.history_s * 1e9))
        for tr in reloaded:
            store.add(tr)
        if reloaded:
            logger.info("reloaded %d track states of %d tracks from %s", len(reloaded), len(store.ids()), state)
        return store

    def _inboxes(
        self, session: Any, listed: list[str]
    ) -> tuple[KeyedInbox[Features], KeyedInbox[SensorInfo], KeyedInbox[PtzState]]:
        """The bounded inboxes of the sensors' Features, SensorInfo and PTZ state: per listed sensor, or (any
        sensor) on their wildcards."""
        k = self.keys
        # Each sensor's Features: a byte budget (its largest frames dropped before copy and decode when over it), and
        # never more than one second of it waiting.
        rate = self.cfg.manager.sensor_bytes_per_s
        budget: dict[str, Any] = {
            "rate_bytes_per_s": rate,
            "max_key_bytes": max(int(rate), MAX_PAYLOAD_BYTES),
            # While over its rate, a sensor's frames larger than its budget spread over 30 frames a second are
            # dropped (the frame rate the budget is sized for: [manager] sensor_bytes_per_s).
            "large_bytes": int(rate / BUDGET_FPS),
        }
        if self.gate.any_sensor:
            logger.warning("manager %s accepts any sensor ([manager] sensors = ['*'])", self.mid)
            return (
                KeyedInbox(
                    session,
                    [k.all_features],
                    Features,
                    capacity=FRAMES_PER_SENSOR,
                    max_keys=4 * MAX_SENSORS,
                    notify=self.wake.set,
                    **budget,
                ),
                KeyedInbox(session, [k.all_sensor_info], SensorInfo, capacity=INFOS_PER_SENSOR, advanced=True),
                KeyedInbox(session, [k.all_ptz_state], PtzState, capacity=PTZ_STATES_PER_SENSOR),
            )
        logger.info("manager %s fuses sensors %s", self.mid, ", ".join(listed))
        return (
            KeyedInbox(
                session,
                [k.sensor_features(s) for s in listed],
                Features,
                capacity=FRAMES_PER_SENSOR,
                notify=self.wake.set,
                **budget,
            ),
            KeyedInbox(
                session, [k.sensor_info(s) for s in listed], SensorInfo, capacity=INFOS_PER_SENSOR, advanced=True
            ),
            KeyedInbox(session, [k.sensor_ptz_state(s) for s in listed], PtzState, capacity=PTZ_STATES_PER_SENSOR),
        )

    # -- zenoh callbacks (enqueue only, or answer from locked state) -----------
    def _on_liveliness(self, sample: Any) -> None:
        try:
            parsed = self.keys.parse(str(sample.key_expr))
        except ConfigError:
            return
        if parsed.kind != "sensor" or not self.gate.allows(parsed.ident):
            return
        self.presence.append((parsed.ident, sample.kind == self._zenoh.SampleKind.PUT))

    def _on_agent_liveliness(self, sample: Any) -> None:
        try:
            parsed = self.keys.parse(str(sample.key_expr))
        except ConfigError:
            return
        if parsed.kind == "agent" and len(self.agent_presence) < 4 * MAX_SENSORS:
            self.agent_presence.append((parsed.ident, sample.kind == self._zenoh.SampleKind.PUT))

    def _fetch_loop(self) -> None:
        """Read the SensorInfo of sensors the tick names, from their own queryables (off the tick and zenoh threads)."""
        while not self.shutdown.is_set():
            try:
                sid = self.fetch_queue.get(timeout=0.5)
            except queue.Empty:
                continue
            if sid is None:
                return
            key = self.keys.sensor_info(sid)
            try:
                for reply in self.session.get(key, timeout=2.0):
                    if reply.ok is None:
                        continue
                    try:
                        info = decode(reply.ok.payload.to_bytes(), SensorInfo)
                    except SchemaError as err:
                        logger.warning("bad SensorInfo reply on %s: %s", reply.ok.key_expr, err)
                        continue
                    self.fetched_infos.append((sid, info))
            except Exception as err:  # session closing, router gone: read again on the next period
                logger.debug("SensorInfo query %s failed: %s", key, err)

    def _on_track_query(self, query: Any) -> None:
        with query:
            if not self.leading:
                return  # the zone's leader answers; a standby's answers would be the same ones twice
            params = dict(query.parameters)
            hist = params.get("history")
            since_ns: int | None = None
            if hist is not None:
                try:
                    seconds = float(hist)
                    if not 0 <= seconds <= MAX_HISTORY_QUERY_S:
                        raise ValueError(hist)
                except ValueError:
                    self.query_errors += 1
                    query.reply_err(f"history must be a number of seconds >= 0, got {hist!r}".encode())
                    return
                since_ns = self.clock.now_ns() - int(seconds * 1e9)
            qke = query.key_expr
            with self.lock:
                ids = [tid for tid in self.store.ids() if qke.intersects(self._zenoh.KeyExpr(self.keys.track(tid)))]
                wildcard = "*" in str(qke)
                replies: list[Track] = []
                for tid in sorted(ids, key=_id_order):
                    if since_ns is None:
                        if wildcard and tid not in self.live_ids:
                            continue
                        latest = self.store.latest(tid)
                        if latest is not None:
                            replies.append(latest)
                    else:
                        replies.extend(self.store.path(tid, since_ns))
            for tr in replies:
                query.reply(self.keys.track(tr.track_id), encode(tr), encoding=MSGPACK)

    def _on_ptz_query(self, query: Any) -> None:
        """Check and queue a PTZ request; the tick applies it and answers (:meth:`_answer_ptz`)."""
        try:
            parsed = self.keys.parse(str(query.key_expr))
            payload = query.payload
            if payload is None:
                raise SchemaError("a PtzRequest payload is required", "$")
            req = decode(payload.to_bytes(), PtzRequest)
        except (SchemaError, ConfigError) as err:
            self._reject(query, f"expected a PtzRequest on {self.keys.ptz_requests(self.mid)}: {err}")
            return
        if self.seat is not None and not self.seat.leading:
            self._reject(query, f"manager {self.mid} stands by for zone {self.seat.zone}: ask {self.seat.leader()}")
            return
        if not self.gate.same_agent(parsed.ident, req.agent_id):
            self._reject(query, f"the request speaks for agent {req.agent_id!r} on agent {parsed.ident!r}'s key")
            return
        with self.lock:
            if len(self.ptz_asks) >= MAX_PENDING_PTZ:
                self._reject(query, "busy: too many PTZ requests waiting, ask again")
                return
            token = next(self.ptz_tokens)
            self.ptz_queries[token] = query
            self.ptz_asks.append(PtzAsk(req, parsed.ident, self.clock.now_ns(), token))
        self.wake.set()

    def _reject(self, query: Any, why: str) -> None:
        self.query_errors += 1
        with query:
            query.reply_err(why[:MAX_TEXT_LEN].encode())

    def _on_old_ptz_query(self, query: Any) -> None:
        self._reject(
            query,
            f"PTZ requests go to {self.keys.manager_ptz(self.mid)}/{{agent_id}}, the agent's own key "
            "(its id as in PtzRequest.agent_id)",
        )

    def _answer_ptz(self, answers: list[PtzAnswer]) -> None:
        now = self.clock.now_ns()
        for ans in answers:
            with self.lock:
                query = self.ptz_queries.pop(ans.token, None)
            req = ans.request
            self.sender_log.log(
                logging.INFO,
                req.agent_id,
                "PTZ %s by %s for %s: %s",
                req.action,
                req.agent_id,
                req.track_id,
                ans.sensor_id or ans.reason,
            )
            if query is None:
                continue
            reply = PtzReply(
                manager_id=self.mid,
                seq=req.seq,
                stamp_ns=now,
                ok=bool(ans.sensor_id),
                track_id=req.track_id,
                sensor_id=ans.sensor_id,
                reason=ans.reason[:MAX_TEXT_LEN],
                lease_s=ans.lease_s,
            )
            try:
                with query:
                    query.reply(self.keys.ptz_request(self.mid, req.agent_id), encode(reply), encoding=MSGPACK)
            except Exception as err:  # the agent gave up (timeout) or the session is closing
                logger.debug("PTZ reply to %s: %s", req.agent_id, err)

    # -- the tick ------------------------------------------------------------------
    def _batch(self) -> Batch:
        self.wake.clear()  # before draining: a sample arriving from here on wakes the next look
        now = self.clock.now_ns()
        presence: dict[str, bool] = {}
        while self.presence:
            sid, alive = self.presence.popleft()
            presence[sid] = alive
            if alive:
                self.info_gate.came_back(sid)
        agents: dict[str, bool] = {}
        while self.agent_presence:
            aid, alive = self.agent_presence.popleft()
            agents[aid] = alive
        if self.census is not None:
            for sid, n in self.census.take().items():
                self.gate.refuse_unlisted(sid, n)
        head = self.sensor_head
        features = []
        for key, data in self.features.drain_raw():
            sid = sender_in_key(key, head)
            f = self.features.decode(key, data)
            if f is not None and self.gate.features(sid, f, now):
                features.append(f)
        if features:
            self.last_frame = time.monotonic()
        states = []
        for key, data in self.ptz_states.drain_raw():
            st = self.ptz_states.decode(key, data)
            if st is not None and self.gate.same_sender(sender_in_key(key, head), st):
                states.append(st)
        with self.lock:
            asks = list(self.ptz_asks)
            self.ptz_asks.clear()
        return Batch(
            features=features,
            infos=self._infos(now),
            ptz_states=states,
            presence=presence,
            ptz_requests=asks,
            agents=agents,
            received_ns=now,
        )

    def _infos(self, now: int) -> list[SensorInfo]:
        """The SensorInfo to take: those put that the gate lets through, and those read from the sensors' own
        queryables (resource_manager/ingest/infos.py)."""
        infos = []
        for key, data in self.infos.drain_raw():
            info = self.infos.decode(key, data)
            if info is not None and self.gate.same_sender(sender_in_key(key, self.sensor_head), info):
                taken = self.info_gate.offer_put(info)
                if taken is not None:
                    infos.append(taken)
        while self.fetched_infos:
            sid, info = self.fetched_infos.popleft()
            if self.gate.same_sender(sid, info):
                read = self.info_gate.offer_read(info, now)
                if read is not None:
                    infos.append(read)
        return infos

    def tick(self) -> TickResult | None:
        """File what arrived; fuse the instant the sensors' watermark allows, if any (None: nothing new yet)."""
        batch = self._batch()
        with self.lock:
            absorbed = self.fusion.absorb(batch)
            alive = self.fusion.sensors.alive()
            t_ns = self.fusion.next_instant(self.clock.now_ns())
        for sid in self.info_gate.due(batch.received_ns, alive):
            self.fetch_queue.put(sid)
        self._answer_ptz(absorbed.ptz_answers)  # PTZ requests are answered as they come, fused instant or not
        self._log_ended(absorbed.ptz_ended)
        if t_ns is None:
            return None
        t0, cpu0 = time.perf_counter(), time.thread_time()
        leading = self.leading
        with self.lock:
            result = self.fusion.step(t_ns)
            fused_s = time.perf_counter() - t0
            self.tick_times.append((fused_s * 1e3, (time.thread_time() - cpu0) * 1e3))
            published_set = self._own(result.trackset) if leading else self._follow()
            kept = [tr for tr in published_set.tracks if self.store.add(tr)] if published_set is not None else []
            if published_set is not None:
                self.live_ids = {tr.track_id for tr in published_set.tracks}
            self.store.prune(t_ns)
            if not result.skipped:
                # this instant's people, also when the published set is an earlier instant's (publish_lag_s)
                self.agreement.update(t_ns, result.views, result.people)
        for sid, n in result.sightings_refused.items():
            self.gate.refusals.add(sid, "sighting", n)
        self.ticks += 1
        if result.skipped or published_set is None:
            return result
        self._log_kept(kept, t_ns)
        if not leading:
            return result
        t1 = time.perf_counter()
        published = self.clock.now_ns()
        self.pub_tracks.put(msgspec.structs.replace(published_set, published_ns=published))
        waited = result.latency
        if waited is not None:
            self.latencies.append(
                Latency(
                    age_ms=max(0.0, (published - t_ns) / 1e6),
                    age_p50_ms=0.0,
                    age_p99_ms=0.0,
                    node_ms=waited.node_ns / 1e6,
                    transport_ms=waited.transport_ns / 1e6,
                    wait_ms=waited.wait_ns / 1e6,
                    fusion_ms=fused_s * 1e3,
                    publish_ms=(time.perf_counter() - t1) * 1e3,
                )
            )
        self.pub_pairs.put(result.pair_choice)
        for plan in result.plans:
            self.session.put(self.keys.plan(plan.sensor_id), encode(plan), encoding=MSGPACK)
        for cmd in result.ptz_commands:
            self.session.put(self.keys.sensor_ptz(cmd.sensor_id), encode(cmd), encoding=MSGPACK)
        self._log_ended(result.ptz_ended)
        for tid in result.ended:
            logger.info("track %s ended", tid)
        return result

    def _log_kept(self, kept: list[Track], t_ns: int) -> None:
        if kept:
            try:
                self.log.append(kept, t_ns)
            except OSError as err:
                self.sender_log.log(logging.ERROR, "track-log", "cannot write the track log: %s", err.strerror)

    def _others(self, leader: str) -> TrackSet | None:
        """Take the TrackSets heard from other managers (the lock held): the neighbours' go to the zone ownership;
        returns the newest of ``leader``'s ("": none wanted)."""
        if self.leader_sets is None:
            return None
        newest = None
        now = self.clock.now_ns()
        for r in self.leader_sets.drain():
            mid = r.msg.manager_id
            if mid == self.mid or r.key != self.keys.tracks():
                continue
            if mid == leader:
                newest = r.msg
            elif self.ownership is not None:
                self.ownership.heard(r.msg, now)
        return newest

    def _own(self, trackset: TrackSet | None) -> TrackSet | None:
        """A leader's tick in a zone with a floor (the lock held): the tracks it owns of ``trackset``
        (resource_manager/serve/zones.py), the others named after the neighbours' tracks of the same people (the id
        a person keeps across a handoff). Without a zone floor, ``trackset`` as it is."""
        self.followed = None
        own = self.ownership
        if own is None:
            return trackset
        self._others("")
        names = after_neighbours(self.fusion, own, self.clock.now_ns())
        if names:
            logger.info("zone manager %s: %d tracks named after its neighbours'", self.mid, len(names))
        if trackset is None:
            return None
        return msgspec.structs.replace(trackset, tracks=own.select(trackset.tracks, self.clock.now_ns()))

    def _follow(self) -> TrackSet | None:
        """A standby's tick (the lock held): its tracks take the ids of the leader's newest TrackSet and, in a zone
        with a floor, the others the neighbours' ids (:func:`standby_names`). Returns the leader's newest TrackSet,
        which is what it keeps as history (and, in a zone, what it owns when it takes over). None: nothing new from
        the leader."""
        if self.leader_sets is None or self.seat is None:
            return None
        leader = self.seat.leader()
        newest = self._others(leader)
        names, theirs = standby_names(self.fusion, newest, self.ownership, self.clock.now_ns())
        # Said at each rename, and the first time it follows this leader even with nothing to rename (a restarted
        # manager whose reloaded tracks already carry the leader's ids).
        if names or (newest is not None and leader != self.followed):
            logger.info("standby %s follows %s: %d tracks renamed", self.mid, leader, len(names))
        if newest is not None:
            self.followed = leader
        if theirs:
            logger.info("standby %s: %d tracks named after its neighbours'", self.mid, len(theirs))
        return newest

    def _log_ended(self, ended: list[tuple[Assignment, str]]) -> None:
        for a, why in ended:
            self.sender_log.log(
                logging.INFO,
                a.agent_id,
                "PTZ %s no longer follows %s for %s: %s",
                a.sensor_id,
                a.track_id,
                a.agent_id,
                why,
            )

    def status(self, result: TickResult | None, period_s: float) -> None:
        inboxes = (self.features, self.infos, self.ptz_states)
        counts = InboxCounts(
            decode_errors=sum(i.counters.decode_errors for i in inboxes) + self.query_errors,
            dropped=sum(i.counters.dropped for i in inboxes),
        )
        self.status_seq += 1
        with self.lock:
            known = self.fusion.known_sensors()
        msg = manager_status(
            self.mid,
            self.status_seq,
            self.clock.now_ns(),
            tick_ms=[wall for wall, _ in self.tick_times],
            tick_cpu_ms=[cpu for _, cpu in self.tick_times],
            period_s=period_s,
            result=result,
            known=known,
            inboxes=counts,
            gate=self.gate,
            refused_partial=self.census is not None and self.census.partial,
            schedule=self.fusion.schedule,
            frames_received=self.fusion.sensors.received,
            latencies=self.latencies,
        )
        with self.lock:
            msg = msgspec.structs.replace(msg, agreement=self.agreement.report()[:MAX_SENSORS])
        if self.seat is not None:
            role = "leader" if self.seat.role == "leader" else "standby"
            msg = msgspec.structs.replace(msg, zone=self.seat.zone, role=role, leader_id=self.seat.leader())
        self.pub_status.put(msg)
        self.sender_log.flush()
        self.tick_times.clear()
        self.latencies.clear()

    def loop(self) -> None:
        # A flood's buffers, once freed, go back to the system (common/memory.py): no residue.
        trimmer = Trimmer()
        status_every = self.cfg.manager.status_period_s
        next_status = time.monotonic() + status_every
        last: TickResult | None = None
        logger.info(
            "manager %s fusing at up to %.1f Hz on prefix %s", self.mid, self.cfg.manager.rate_hz, self.keys.root
        )
        while not self.shutdown.is_set():
            last = self.tick() or last
            if self.census is not None:
                self.census.tick()
            now = time.monotonic()
            if now >= next_status:
                self.status(last, status_every)
                next_status = now + status_every
            trimmer.tick()
            # Sleep until a frame arrives or a sensor's deadline passes: a fusion waits for the watermark, not a
            # timer.
            with self.lock:
                due_ns = self.fusion.until_due_ns(self.clock.now_ns())
            sleep_s = MAX_SLEEP_S if due_ns is None else min(MAX_SLEEP_S, due_ns / 1e9)
            sleep_s = min(sleep_s, max(0.0, next_status - now))
            self.wake.wait(sleep_s)

    def close(self) -> None:
        self.fetch_queue.put(None)
        if self.seat is not None:
            self.seat.close()
        if self.leader_sets is not None:
            self.leader_sets.close()
        for ent in (self.q_tracks, self.q_ptz, self.q_ptz_old, self.live_sub, self.agent_sub, self.token):
            try:
                ent.undeclare()
            except Exception as err:  # already closed with the session
                logger.debug("undeclare: %s", err)
        with self.lock:
            pending = list(self.ptz_queries.values())
            self.ptz_queries.clear()
        for query in pending:
            try:
                query.drop()
            except Exception as err:
                logger.debug("drop PTZ query: %s", err)
        if self.census is not None:
            self.census.close()
        for inbox in (self.features, self.infos, self.ptz_states):
            inbox.close()
        for pub in (self.pub_tracks, self.pub_pairs, self.pub_status):
            pub.close()
        self.log.close()


def after_neighbours(fusion: Fusion, own: ZoneOwnership, now_ns: int) -> dict[int, str]:
    """A zone manager's tracks of people it does not own named after the neighbours' published tracks of them
    (resource_manager/serve/zones.py): the id a person keeps across a handoff. The owned ones keep theirs."""
    return fusion.adopt(own.theirs(now_ns), keep=frozenset(own.owned))


def standby_names(
    fusion: Fusion, leader: TrackSet | None, own: ZoneOwnership | None, now_ns: int
) -> tuple[dict[int, str], dict[int, str]]:
    """A standby's renames at one tick, serial -> id: its tracks named after those of its leader's newest TrackSet
    (``leader``, None: nothing new heard), which the leader owns; and, in a zone, the others named after the
    neighbours' (as the leader names them, :func:`after_neighbours`), also while no leader is heard. Otherwise a
    person who crosses into the zone while its leader is gone and before the standby has taken over (a lease) would
    be published under the standby's own id, not the one the neighbour published them under."""
    names = fusion.adopt(leader.tracks) if leader is not None else {}
    if own is None:
        return names, {}
    if leader is not None:
        own.owned = {t.track_id for t in leader.tracks}
    return names, after_neighbours(fusion, own, now_ns)


def _id_order(tid: str) -> tuple[str, int]:
    head, _, tail = tid.rpartition("-")
    return (head, int(tail)) if tail.isdigit() else (tid, 0)


def run(cfg: ManagerConfig) -> int:
    """Run a manager until SIGINT/SIGTERM; returns the exit code."""
    if not cfg.manager.sensors:
        raise ConfigError(
            f"manager {cfg.manager.id}: no sensors to fuse: run it from its site (--site FILE), list them in "
            '[manager] sensors, or set sensors = ["*"] to accept any sensor'
        )
    shutdown = install_signal_handlers()
    pin_mmap_threshold()  # before zenoh allocates: large buffers are mapped alone and unmapped when freed
    clock = NtpClock.from_settings(cfg.clock)
    clock.start()
    try:
        with open_session(cfg.zenoh) as session:
            mid = cfg.manager.id
            refuse_second(
                session, Keys(cfg.manager.prefix).manager(mid), f"manager {mid}", cfg.zenoh.lease_ms / 1e3 + 1.0
            )
            node = ManagerNode(session, cfg, clock, shutdown)
            try:
                node.loop()
            finally:
                node.close()
    finally:
        clock.stop()
    logger.info("manager %s stopped", cfg.manager.id)
    return 0
