"""The sensor-node shell: capture thread -> pipeline -> zenoh.

* **Capture** runs on its own thread into a one-frame *latest slot*: when the
  pipeline is slower than the camera, the older frame is replaced (and
  counted as dropped), so latency never builds up. Frames are stamped at
  capture on the NTP-corrected clock.
* **Publishes** (keys from :class:`common.keys.Keys`): Features per frame on
  ``sensor/{id}/features``; SensorInfo as a queryable on ``sensor/{id}/info``
  and put whenever it changes, by an AdvancedPublisher whose cache serves
  late joiners (AdvancedSubscriber history); NodeStatus at 1 Hz on ``sensor/{id}/status``
  (fps, drops, processing time, clock offset/uncertainty, decode errors,
  source state and message); a liveliness token ``sensor/{id}``.
* **Subscribes**: PTZ nodes take PtzCommand on ``sensor/{id}/ptz`` and put
  PtzState on ``sensor/{id}/ptz/state`` when the head moves; a node whose
  platform follows view plans (``NodeParts.plans``: a mobile robot's driver)
  takes every ViewPlan (``plan/*``) and hands it over, so mobile robots drive
  where the manager plans (closed loop).
* **Shutdown**: SIGINT/SIGTERM set a flag; the loop ends, the capture thread
  is joined, the session closed.
"""

from __future__ import annotations

import logging
import threading
import time
from typing import Any

import msgspec

from common.clock import NtpClock
from common.codec import encode
from common.frames import Frame
from common.memory import Trimmer
from common.schema import NodeStatus, PtzCommand, PtzState, SensorInfo, SourceState, ViewPlan
from common.session import MSGPACK, Shutdown, install_signal_handlers, open_session, refuse_second
from common.transport import Inbox, TypedPublisher
from sensor_node.build import NodeParts, build_node, sensor_info
from sensor_node.config import NodeConfig

__all__ = ["LatestSlot", "SensorNode", "run_node"]

logger = logging.getLogger(__name__)

STATUS_PERIOD_S = 1.0

INFO_OFFSET_CHANGE_NS = 1_000_000
"""SensorInfo is put again when the clock offset moved by this much (1 ms) or more."""

PIPELINE_MESSAGES = {
    "warmup": "learning the background: no blobs yet",
    "moving": "camera moving: no blobs until it stops and the background is relearnt",
    "reinit": "abnormal change: relearning the background",
}
"""NodeStatus.message while the pipeline reports no blobs (when the source has nothing to say)."""


class LatestSlot:
    """A one-frame mailbox: ``put`` replaces an unread frame (counted as dropped)."""

    def __init__(self) -> None:
        self._cond = threading.Condition()
        self._frame: Frame | None = None
        self.dropped = 0
        self.closed = False

    def put(self, frame: Frame) -> None:
        with self._cond:
            if self._frame is not None:
                self.dropped += 1
            self._frame = frame
            self._cond.notify()

    def count_dropped(self, n: int) -> None:
        """Frames the source itself skipped (it was late) count as dropped too."""
        with self._cond:
            self.dropped += n

    def close(self) -> None:
        with self._cond:
            self.closed = True
            self._cond.notify()

    def get(self, timeout_s: float) -> Frame | None:
        with self._cond:
            if self._frame is None and not self.closed:
                self._cond.wait(timeout_s)
            frame, self._frame = self._frame, None
            return frame


class SensorNode:
    """One running sensor node (the session is opened by :func:`run_node`)."""

    def __init__(self, cfg: NodeConfig, session: Any, clock: NtpClock, parts: NodeParts, shutdown: Shutdown) -> None:
        self.cfg = cfg
        self.session = session
        self.clock = clock
        self.parts = parts
        self.shutdown = shutdown
        self.keys = cfg.keys
        sid = cfg.node.id
        self.slot = LatestSlot()
        self._stop = threading.Event()
        self._capture = threading.Thread(target=self._capture_loop, name=f"capture-{sid}", daemon=True)
        self.pub_features = TypedPublisher(session, self.keys.sensor_features(sid))
        self.pub_status = TypedPublisher(session, self.keys.sensor_status(sid))
        # An AdvancedPublisher: late joiners (managers, agents) get the cached SensorInfo from its history.
        self.pub_info = TypedPublisher(session, self.keys.sensor_info(sid), reliable_block=True, cache_samples=1)
        self.inboxes: list[Inbox[Any]] = []
        self.ptz_inbox: Inbox[PtzCommand] | None = None
        self.plan_inbox: Inbox[ViewPlan] | None = None
        self.pub_ptz: TypedPublisher | None = None
        if parts.ptz is not None:
            self.ptz_inbox = Inbox(session, self.keys.sensor_ptz(sid), PtzCommand, capacity=64, drop_oldest=False)
            self.pub_ptz = TypedPublisher(session, self.keys.sensor_ptz_state(sid), reliable_block=True)
            self.inboxes.append(self.ptz_inbox)
        if parts.plans is not None:
            self.plan_inbox = Inbox(session, self.keys.all_plans, ViewPlan, capacity=256)
            self.inboxes.append(self.plan_inbox)
        self.model = parts.model
        """The camera model SensorInfo describes (a PTZ head's changes as it comes to rest)."""
        self._info_lock = threading.Lock()
        self._info_seq = 0
        self._info: SensorInfo = self._make_info()
        self._info_bytes = encode(self._info)
        self._queryable = session.declare_queryable(self.keys.sensor_info(sid), self._on_info_query)
        self._token = session.liveliness().declare_token(self.keys.sensor(sid))
        self.seq = 0
        self.frames = 0
        self._interval_frames = 0
        self._interval_ms = 0.0
        self._status_seq = 0
        self._ptz_seq = 0
        self._last_ptz: tuple[float, float, float, bool] | None = None
        self.capture_error = ""
        self.pipeline_state = "starting"
        """The background model's verdict on the latest frame ("ok", "warmup", "moving", ...)."""

    # -- SensorInfo ---------------------------------------------------------------------------------
    def _make_info(self) -> SensorInfo:
        st = self.clock.status()
        return sensor_info(
            self.cfg,
            self.parts,
            model=self.model,
            seq=self._info_seq,
            stamp_ns=self.clock.now_ns(),
            clock_offset_ns=int(st.offset_ns),
            clock_uncertainty_ns=int(st.uncertainty_ns),
            clock_source=st.source,
        )

    def _refresh_info(self) -> None:
        """Put SensorInfo when anything but its stamp changed (clock source, offset by > 1 ms, model)."""
        new = self._make_info()
        old = self._info
        same = (
            msgspec.structs.replace(new, seq=old.seq, stamp_ns=old.stamp_ns, clock_uncertainty_ns=0)
            == (msgspec.structs.replace(old, clock_uncertainty_ns=0, clock_offset_ns=new.clock_offset_ns))
            and abs(new.clock_offset_ns - old.clock_offset_ns) < INFO_OFFSET_CHANGE_NS
        )
        if same:
            return
        self._info_seq += 1
        new = msgspec.structs.replace(new, seq=self._info_seq)
        with self._info_lock:
            self._info, self._info_bytes = new, encode(new)
        self.pub_info.put(new)

    def _on_info_query(self, query: Any) -> None:
        # zenoh's thread: reply with the pre-encoded latest info only.
        with query:
            with self._info_lock:
                data = self._info_bytes
            query.reply(self.keys.sensor_info(self.cfg.node.id), data, encoding=MSGPACK)

    # -- capture ------------------------------------------------------------------------------------
    def _capture_loop(self) -> None:
        try:
            while not self._stop.is_set():
                frame = self.parts.source.read(self._stop)
                if frame is None:
                    break
                self.slot.put(frame)
                if frame.skipped:
                    self.slot.count_dropped(frame.skipped)
        except Exception as err:  # a bug or an unrecoverable source: report, and let the main loop exit
            logger.exception("capture failed")
            self.capture_error = f"capture failed: {err}"
        finally:
            self.slot.close()

    # -- main loop ----------------------------------------------------------------------------------
    def _handle_inputs(self) -> None:
        if self.ptz_inbox is not None and self.parts.ptz is not None:
            for r in self.ptz_inbox.drain():
                cmd = r.msg
                if cmd.sensor_id != self.cfg.node.id:
                    continue
                logger.info(
                    "PTZ command from %s: pan %.3f tilt %.3f zoom %.2f",
                    cmd.manager_id,
                    cmd.pan_rad,
                    cmd.tilt_rad,
                    cmd.zoom,
                )
                self.parts.ptz.driver.command(cmd.pan_rad, cmd.tilt_rad, cmd.zoom)
        if self.plan_inbox is not None and self.parts.plans is not None:
            for rp in self.plan_inbox.drain():
                self.parts.plans.follow(rp.msg)

    def _publish_ptz(self) -> None:
        if self.parts.ptz is None or self.pub_ptz is None:
            return
        p = self.parts.ptz.driver.pose(self.clock.now_ns())
        state = (round(p.pan_rad, 4), round(p.tilt_rad, 4), round(p.zoom, 3), p.moving)
        if state == self._last_ptz:
            return
        self._last_ptz = state
        self.pub_ptz.put(
            PtzState(
                sensor_id=self.cfg.node.id,
                seq=self._ptz_seq,
                stamp_ns=self.clock.now_ns(),
                pan_rad=p.pan_rad,
                tilt_rad=max(-1.5707, min(1.5707, p.tilt_rad)),
                zoom=p.zoom,
                moving=p.moving,
            )
        )
        self._ptz_seq += 1
        if not p.moving:
            self.model = self.parts.ptz.model(p)

    def _publish_status(self, elapsed_s: float) -> None:
        st = self.clock.status()
        src = self.parts.source
        state: SourceState = src.state
        message = self.capture_error or src.message or PIPELINE_MESSAGES.get(self.pipeline_state, "")
        decode_errors = sum(i.counters.decode_errors for i in self.inboxes)
        dropped_msgs = sum(i.counters.dropped for i in self.inboxes)
        n = self._interval_frames
        self.pub_status.put(
            NodeStatus(
                sensor_id=self.cfg.node.id,
                seq=self._status_seq,
                stamp_ns=self.clock.now_ns(),
                fps=n / elapsed_s if elapsed_s > 0 else 0.0,
                frames=self.frames,
                dropped_frames=self.slot.dropped,
                processing_ms=self._interval_ms / n if n else 0.0,
                clock_offset_ns=int(st.offset_ns),
                clock_uncertainty_ns=int(st.uncertainty_ns),
                clock_source=st.source,
                decode_errors=decode_errors,
                dropped_msgs=dropped_msgs,
                source_state=state,
                message=message[:256],
            )
        )
        self._status_seq += 1
        self._interval_frames = 0
        self._interval_ms = 0.0

    def run(self, max_frames: int = 0) -> int:
        """Process frames until shutdown, the end of the source, or ``max_frames`` published."""
        self.pub_info.put(self._info)
        self._capture.start()
        last_status = time.monotonic()
        self._publish_status(0.0)
        trimmer = Trimmer()  # frames freed after a busy spell go back to the system (common/memory.py)
        try:
            while not self.shutdown.is_set():
                trimmer.tick()
                self._handle_inputs()
                self._publish_ptz()
                frame = self.slot.get(timeout_s=0.1)
                now = time.monotonic()
                if now - last_status >= STATUS_PERIOD_S:
                    self._refresh_info()
                    self._publish_status(now - last_status)
                    last_status = now
                if frame is None:
                    if self.slot.closed and not self._capture.is_alive():
                        if self.capture_error:
                            return 1
                        # The source ended: stay up (status says "ended") until asked to stop, or exit.
                        self._publish_status(max(now - last_status, 1e-3))
                        if self.parts.exit_at_end:
                            logger.info("source ended after %d frames: exiting ([source] at_end = exit)", self.frames)
                            break
                        while not self.shutdown.sleep(STATUS_PERIOD_S):
                            self._publish_status(STATUS_PERIOD_S)
                        break
                    continue
                t0 = time.perf_counter()
                features, self.pipeline_state = self.parts.processor.process_frame(frame, self.seq)
                proc_ms = (time.perf_counter() - t0) * 1e3
                latency_ms = max(0.0, (self.clock.now_ns() - frame.stamp_ns) / 1e6)
                self.pub_features.put(msgspec.structs.replace(features, processing_ms=min(latency_ms, 1e9)))
                self.seq += 1
                self.frames += 1
                self._interval_frames += 1
                self._interval_ms += proc_ms
                if max_frames and self.frames >= max_frames:
                    break
        finally:
            self.close()
        return 0

    def close(self) -> None:
        """Stop capture and undeclare everything (the session is closed by the caller)."""
        self._stop.set()
        self._capture.join(timeout=5.0)
        for inbox in self.inboxes:
            inbox.close()
        for pub in (self.pub_features, self.pub_status, self.pub_info, self.pub_ptz):
            if pub is not None:
                pub.close()
        for ent in (self._queryable, self._token):
            try:
                ent.undeclare()
            except Exception as err:  # already gone with the session
                logger.debug("undeclare: %s", err)
        self.parts.source.close()


def run_node(cfg: NodeConfig, max_frames: int = 0) -> int:
    """Run a sensor node from its config until SIGINT/SIGTERM; returns the exit code."""
    shutdown = install_signal_handlers()
    clock = NtpClock.from_settings(cfg.clock)
    clock.start()
    try:
        parts = build_node(cfg, clock.now_ns)
        # Timestamps: what the SensorInfo publisher's cache (zenoh.ext) orders its samples by.
        with open_session(cfg.zenoh, extra={"timestamping/enabled": True}) as session:
            sid = cfg.node.id
            refuse_second(session, cfg.keys.sensor(sid), f"sensor node {sid}", cfg.zenoh.lease_ms / 1e3 + 1.0)
            node = SensorNode(cfg, session, clock, parts, shutdown)
            logger.info(
                "sensor node %s up: %s source, %s camera, features on %s",
                cfg.node.id,
                type(parts.source).__name__,
                parts.kind,
                cfg.keys.sensor_features(cfg.node.id),
            )
            return node.run(max_frames)
    finally:
        clock.stop()
