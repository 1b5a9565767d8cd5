"""The resource manager process: zenoh in, :class:`~resource_manager.fusion.Fusion` per tick, zenoh out.

Subscriptions (decoded on the tick thread, never on zenoh's): every sensor's
Features, SensorInfo and PTZ state; the sensors' liveliness tokens (presence;
a sensor that appears is asked for its SensorInfo). Each tick at ``rate_hz``:
fuse at ``now - latency`` on the NTP-corrected clock, then publish the
TrackSet on ``tracks``, each track on ``track/{id}``, the pair choices on
``manager/{id}/pairs``, view plans on ``plan/{sensor}``, PTZ commands on
``sensor/{id}/ptz``; ManagerStatus at 1 Hz. Queryables answer ``track/*``
(latest state, or the path with ``?history=SECONDS``) and PTZ allocation
requests on ``manager/{id}/ptz``. The track history is logged to disk and
reloaded at start (:mod:`resource_manager.serve.history`).
"""

from __future__ import annotations

import logging
import queue
import threading
import time
from collections import deque
from pathlib import Path
from typing import Any

import numpy as np

from common.clock import NtpClock
from common.codec import decode, encode
from common.errors import ConfigError, SchemaError
from common.geometry import wrap_angle
from common.keys import Keys
from common.schema import Features, ManagerStatus, Pose, PtzReply, PtzRequest, PtzState, SensorInfo, Track
from common.schema import PoseEstimate as WirePoseEstimate
from common.session import MSGPACK, Shutdown, install_signal_handlers, open_session
from common.transport import Inbox, TypedPublisher
from resource_manager.config import ManagerConfig
from resource_manager.fusion import Batch, Fusion, TickResult
from resource_manager.serve.history import IdAllocator, TrackLog, TrackStore, read_segments

__all__ = ["ManagerNode", "run"]

POLL_S = 0.005
"""How often the manager looks whether the sensors' watermark allows a new fusion."""

logger = logging.getLogger(__name__)


class ManagerNode:
    """Everything one manager process holds; ``loop()`` runs until ``shutdown``."""

    def __init__(self, session: Any, cfg: ManagerConfig, clock: NtpClock, shutdown: Shutdown) -> None:
        import zenoh

        self._zenoh = zenoh
        self.session = session
        self.cfg = cfg
        self.clock = clock
        self.shutdown = shutdown
        self.keys = Keys(cfg.manager.prefix)
        self.mid = cfg.manager.id
        state = Path(cfg.manager.state_dir)
        self.ids = IdAllocator(state, self.mid)
        self.store = TrackStore(cfg.manager.history_s, cfg.manager.history_hz)
        now = clock.now_ns()
        reloaded = read_segments(state / "tracks", now - int(cfg.manager.history_s * 1e9))
        for tr in reloaded:
            self.store.add(tr)
        if reloaded:
            logger.info("reloaded %d track states of %d tracks from %s", len(reloaded), len(self.store.ids()), state)
        self.log = TrackLog(state / "tracks", cfg.manager.segment_s, cfg.manager.retain_s)
        self.fusion = Fusion(cfg, new_id=self.ids)
        self.lock = threading.Lock()
        self.live_ids: set[str] = set()
        self.presence: deque[tuple[str, bool]] = deque()
        self.fetched_infos: deque[SensorInfo] = deque()
        self.fetch_queue: queue.Queue[str | None] = queue.Queue()
        self.query_errors = 0
        k = self.keys
        self.features = Inbox(session, k.all_features, Features, capacity=8192)
        self.infos = Inbox(session, k.all_sensor_info, SensorInfo, capacity=256)
        self.ptz_states = Inbox(session, k.all_ptz_state, PtzState, capacity=256)
        self.pub_tracks = TypedPublisher(session, k.tracks(), reliable_block=True)
        self.pub_pairs = TypedPublisher(session, k.manager_pairs(self.mid))
        self.pub_status = TypedPublisher(session, k.manager_status(self.mid), reliable_block=True)
        self.token = session.liveliness().declare_token(k.manager(self.mid))
        self.live_sub = session.liveliness().declare_subscriber(k.all_sensors, self._on_liveliness, history=True)
        self.q_tracks = session.declare_queryable(k.all_tracks, self._on_track_query)
        self.q_ptz = session.declare_queryable(k.manager_ptz(self.mid), self._on_ptz_query)
        self.fetcher = threading.Thread(target=self._fetch_loop, name="sensor-info-fetch", daemon=True)
        self.fetcher.start()
        self.fetch_queue.put("*")
        self.tick_ms: list[float] = []
        self.status_seq = 0
        self.ticks = 0

    # -- zenoh callbacks (enqueue only, or answer from locked state) -----------
    def _on_liveliness(self, sample: Any) -> None:
        try:
            parsed = self.keys.parse(str(sample.key_expr))
        except ConfigError:
            return
        if parsed.kind != "sensor":
            return
        alive = sample.kind == self._zenoh.SampleKind.PUT
        self.presence.append((parsed.ident, alive))
        if alive:
            self.fetch_queue.put(parsed.ident)

    def _fetch_loop(self) -> None:
        """Ask sensors that appear for their SensorInfo (off the tick and zenoh threads)."""
        while not self.shutdown.is_set():
            try:
                sid = self.fetch_queue.get(timeout=0.5)
            except queue.Empty:
                continue
            if sid is None:
                return
            key = self.keys.all_sensor_info if sid == "*" else self.keys.sensor_info(sid)
            try:
                for reply in self.session.get(key, timeout=2.0):
                    if reply.ok is None:
                        continue
                    try:
                        self.fetched_infos.append(decode(reply.ok.payload.to_bytes(), SensorInfo))
                    except SchemaError as err:
                        logger.warning("bad SensorInfo reply on %s: %s", reply.ok.key_expr, err)
            except Exception as err:  # session closing, router gone: try again on the next appearance
                logger.debug("SensorInfo query %s failed: %s", key, err)

    def _on_track_query(self, query: Any) -> None:
        with query:
            params = dict(query.parameters)
            hist = params.get("history")
            since_ns: int | None = None
            if hist is not None:
                try:
                    seconds = float(hist)
                    if not 0 <= seconds <= 1e7:
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
        with query:
            payload = query.payload
            try:
                if payload is None:
                    raise SchemaError("a PtzRequest payload is required", "$")
                req = decode(payload.to_bytes(), PtzRequest)
            except SchemaError as err:
                self.query_errors += 1
                query.reply_err(f"expected a PtzRequest: {err}".encode())
                return
            now = self.clock.now_ns()
            with self.lock:
                alloc = self.fusion.ptz
                if req.action == "acquire":
                    target = self.fusion.ptz_targets().get(req.track_id)
                    sid, reason = alloc.acquire(req.agent_id, target, req.track_id, req.priority, now)
                else:
                    sid, reason = alloc.release(req.agent_id, req.track_id)
            reply = PtzReply(
                manager_id=self.mid,
                seq=req.seq,
                stamp_ns=now,
                ok=bool(sid),
                track_id=req.track_id,
                sensor_id=sid,
                reason=reason[:256],
            )
            logger.info("PTZ %s by %s for %s: %s", req.action, req.agent_id, req.track_id, sid or reason)
            query.reply(self.keys.manager_ptz(self.mid), encode(reply), encoding=MSGPACK)

    # -- the tick ------------------------------------------------------------------
    def _batch(self) -> Batch:
        presence: dict[str, bool] = {}
        while self.presence:
            sid, alive = self.presence.popleft()
            presence[sid] = alive
        infos = [r.msg for r in self.infos.drain()]
        while self.fetched_infos:
            infos.append(self.fetched_infos.popleft())
        return Batch(
            features=[r.msg for r in self.features.drain()],
            infos=infos,
            ptz_states=[r.msg for r in self.ptz_states.drain()],
            presence=presence,
        )

    def tick(self) -> TickResult | None:
        """File what arrived; fuse the instant the sensors' watermark allows, if any (None: nothing new yet)."""
        batch = self._batch()
        with self.lock:
            self.fusion.absorb(batch)
            t_ns = self.fusion.next_instant(self.clock.now_ns())
        if t_ns is None:
            return None
        t0 = time.perf_counter()
        with self.lock:
            result = self.fusion.step(Batch(), t_ns)
            self.tick_ms.append((time.perf_counter() - t0) * 1e3)
            kept = [tr for tr in result.trackset.tracks if self.store.add(tr)]
            self.live_ids = {tr.track_id for tr in result.trackset.tracks}
            self.store.prune(t_ns)
        self.ticks += 1
        if result.skipped:
            return result
        if kept:
            try:
                self.log.append(kept, t_ns)
            except OSError as err:
                logger.error("cannot write the track log: %s", err.strerror)
        self.pub_tracks.put(result.trackset)
        for tr in result.trackset.tracks:
            self.session.put(self.keys.track(tr.track_id), encode(tr), encoding=MSGPACK)
        self.pub_pairs.put(result.pair_choice)
        for plan in result.plans:
            self.session.put(self.keys.plan(plan.sensor_id), encode(plan), encoding=MSGPACK)
        for cmd in result.ptz_commands:
            self.session.put(self.keys.sensor_ptz(cmd.sensor_id), encode(cmd), encoding=MSGPACK)
        for a, why in self.fusion.ptz.ended:
            logger.info("PTZ %s no longer follows %s for %s: %s", a.sensor_id, a.track_id, a.agent_id, why)
        self.fusion.ptz.ended.clear()
        for tid in result.ended:
            logger.info("track %s ended", tid)
        return result

    def status(self, result: TickResult | None, period_s: float) -> None:
        ms = np.asarray(self.tick_ms or [0.0])
        c = result.counters if result is not None else None
        inboxes = (self.features, self.infos, self.ptz_states)
        self.status_seq += 1
        msg = ManagerStatus(
            manager_id=self.mid,
            seq=self.status_seq,
            stamp_ns=self.clock.now_ns(),
            tick_ms=float(ms.mean()),
            tick_p99_ms=float(np.percentile(ms, 99)),
            tick_rate_hz=len(self.tick_ms) / period_s,
            sensors_in_use=(c.sensors_in_use if c else [])[:64],
            sensors_known=(c.sensors_known if c else [])[:64],
            sensors_without_pose=(c.sensors_without_pose if c else [])[:64],
            tracks=len(result.trackset.tracks) if result else 0,
            decode_errors=sum(i.counters.decode_errors for i in inboxes) + self.query_errors,
            late_msgs=c.late if c else 0,
            duplicate_msgs=c.duplicate if c else 0,
            out_of_order_msgs=c.out_of_order if c else 0,
            dropped_msgs=sum(i.counters.dropped for i in inboxes) + (c.dropped if c else 0),
            sensors_absent=(c.sensors_absent if c else [])[:64],
            poses=[
                WirePoseEstimate(
                    sensor_id=p.sensor_id,
                    pose=Pose(x_m=p.x_m, y_m=p.y_m, z_m=p.z_m, yaw_rad=wrap_angle(p.yaw_rad)),
                    source=p.source,
                    sigma_m=p.sigma_xy_m,
                )
                for p in (c.poses if c else ())[:64]
            ],
        )
        self.pub_status.put(msg)
        self.tick_ms.clear()

    def loop(self) -> None:
        status_every = self.cfg.manager.status_period_s
        next_status = time.monotonic() + status_every
        last: TickResult | None = None
        logger.info(
            "manager %s fusing at up to %.1f Hz on prefix %s", self.mid, self.cfg.manager.rate_hz, self.keys.root
        )
        while not self.shutdown.is_set():
            last = self.tick() or last
            now = time.monotonic()
            if now >= next_status:
                self.status(last, status_every)
                next_status = now + status_every
            # Frames arrive at the cameras' pace: look again soon (a fusion waits for the watermark, not a timer).
            if self.shutdown.sleep(POLL_S):
                break

    def close(self) -> None:
        self.fetch_queue.put(None)
        for ent in (self.q_tracks, self.q_ptz, self.live_sub, self.token):
            try:
                ent.undeclare()
            except Exception as err:  # already closed with the session
                logger.debug("undeclare: %s", err)
        for inbox in (self.features, self.infos, self.ptz_states):
            inbox.close()
        for pub in (self.pub_tracks, self.pub_pairs, self.pub_status):
            pub.close()
        self.log.close()


def _id_order(tid: str) -> tuple[str, int]:
    head, _, tail = tid.rpartition("-")
    return (head, int(tail)) if tail.isdigit() else (tid, 0)


def run(cfg: ManagerConfig) -> int:
    """Run a manager until SIGINT/SIGTERM; returns the exit code."""
    shutdown = install_signal_handlers()
    clock = NtpClock.from_settings(cfg.clock)
    clock.start()
    try:
        with open_session(cfg.zenoh) as session:
            node = ManagerNode(session, cfg, clock, shutdown)
            try:
                node.loop()
            finally:
                node.close()
    finally:
        clock.stop()
    logger.info("manager %s stopped", cfg.manager.id)
    return 0
