"""The manager's whole per-tick computation, pure: received messages in, tracks and commands out.

``Fusion(config).step(batch, t_ns)`` runs, at the fusion instant ``t_ns``, in the paper's order:

1. ingest (bounded buffers; late, duplicate, out-of-order counted) and align every sensor's blobs to ``t_ns``
   by NTP stamps and interpolation (:mod:`~resource_manager.ingest`);
2. poses: surveyed ones plus mutual calibration, Eq. (3) (:mod:`~resource_manager.poses`);
3. views: every camera's blobs in world terms, and which cameras can see now (:mod:`~resource_manager.views`);
4. track: per view, blobs assigned to the predicted tracks; each track updated with its views, new people
   paired across views by Eq. (7) and the error model, existence and life cycle (:mod:`~resource_manager.track`,
   which uses :mod:`~resource_manager.stereo` for Eqs. 1, 2, 7 and the pair ranking);
5. view plans for mobile cameras (Eqs. 4-6, :mod:`~resource_manager.plan`) and PTZ pointing
   (:mod:`~resource_manager.serve`).

No zenoh, no disk: tests and benchmarks feed it recorded or synthetic messages;
:mod:`resource_manager.node` is the thin shell around it.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from common.angles import wrap_angle
from common.schema import (
    MAX_SENSORS,
    MAX_TRACKS,
    DetectorState,
    Features,
    PairChoice,
    PairEntry,
    PtzCommand,
    PtzState,
    SensorInfo,
    Track,
    TrackSet,
    ViewPlan,
)
from resource_manager import wiring
from resource_manager.config import ManagerConfig
from resource_manager.ingest.align import AlignedView, AlignParams, align_sensor
from resource_manager.ingest.buffers import Ingest
from resource_manager.plan.scene import HEAD_HEIGHT_M, PlanTarget, plan_camera
from resource_manager.poses.solver import PoseEstimate
from resource_manager.serve.lag import LaggedInstant, LaggedTracks
from resource_manager.serve.ptz import PtzAnswer, PtzAsk, PtzTarget
from resource_manager.track.tracker import TrackSnapshot
from resource_manager.views.blobs import ViewBlobs
from resource_manager.views.build import build_views

__all__ = ["Batch", "Fusion", "TickCounters", "TickResult"]

HOLD_PERIODS = 0.6
"""A sensor's blobs are held or extrapolated at most this many of its frame periods past its nearest frame."""
GAP_PERIODS = 2.5
"""Two frames up to this many periods apart are interpolated between (one missing frame between them is fine)."""
STALE_PERIODS = 3.0
"""A sensor whose newest frame is older than this many periods sits out the tick."""


@dataclass(frozen=True, slots=True)
class Batch:
    """Everything received since the previous tick."""

    features: Sequence[Features] = ()
    infos: Sequence[SensorInfo] = ()
    ptz_states: Sequence[PtzState] = ()
    presence: Mapping[str, bool] = field(default_factory=dict)
    """Liveliness changes: sensor id -> alive."""
    ptz_requests: Sequence[PtzAsk] = ()
    """PTZ requests, answered in the tick (``Fusion.ptz_answers``): the allocation changes on one thread."""
    agents: Mapping[str, bool] = field(default_factory=dict)
    """Liveliness changes of user agents: agent id -> alive (a gone agent's PTZ holds end)."""
    received_ns: int = 0
    """When these features arrived (the manager's clock); 0: each at its own capture stamp plus its node's
    processing (dataset time)."""


@dataclass(frozen=True, slots=True)
class TickCounters:
    sensors_in_use: list[str]
    sensors_known: list[str]
    sensors_without_pose: list[str]
    late: int
    duplicate: int
    out_of_order: int
    dropped: int
    clock_steps: int
    skipped_ticks: int
    sensors_absent: list[str] = field(default_factory=list)
    """Sensors seen before whose liveliness token is gone."""
    poses: tuple[PoseEstimate, ...] = ()
    """Every pose known at the fusion instant."""


@dataclass(frozen=True, slots=True)
class TickResult:
    trackset: TrackSet | None
    """The tracks to publish now: this instant's, or with ``publish_lag_s`` an earlier instant's (None while the
    first ones are held)."""
    pair_choice: PairChoice
    plans: list[ViewPlan]
    ptz_commands: list[PtzCommand]
    counters: TickCounters
    ended: list[str]
    """Ids of the tracks that ended this tick."""
    skipped: bool = False
    """True when ``t_ns`` was not after the previous instant (nothing changed)."""


def _clip(v: float, lo: float, hi: float) -> float:
    """np.clip for one number (NaN stays NaN), without numpy's per-call cost."""
    v = float(v)
    return v if math.isnan(v) else min(max(v, lo), hi)


def _counter_ids(prefix: str) -> Callable[[], str]:
    n = itertools.count(1)
    return lambda: f"{prefix}-{next(n)}"


class Fusion:
    """The resource manager's state and its per-tick pipeline.

    Args:
        config: the manager config.
        new_id: returns the next unique track id (default: an in-memory counter;
            the node passes the persisted allocator of :mod:`resource_manager.serve.history`).
    """

    def __init__(self, config: ManagerConfig, new_id: Callable[[], str] | None = None) -> None:
        self.config = config
        m = config.manager
        self.manager_id = m.id
        self.ingest = Ingest(m.buffer_frames, int(m.clock_step_ms * 1e6))
        self.align_params = wiring.align_params(config)
        self.schedule = wiring.schedule(config)
        self.poses = wiring.pose_solver(config)
        self.tracker = wiring.tracker(config, new_id or _counter_ids(m.id))
        self.feet = wiring.feet_model(config)
        self.planner = wiring.view_planner(config)
        self.trust = wiring.view_trust(config)
        self.ptz = wiring.ptz_allocator(config)
        self.present: dict[str, bool] = {}
        self.last_t_ns = 0
        self.seq = 0
        self.plan_seq = 0
        self.ptz_seq = 0
        self.skipped_ticks = 0
        self.last_poses: dict[str, PoseEstimate] = {}
        self.last_views: dict[str, ViewBlobs] = {}
        """The views of the last fused instant (read by the cameras' agreement check, poses/agreement.py)."""
        self.last_result: TickResult | None = None
        lag = m.publish_lag_s
        self.lagged = LaggedTracks(int(lag * 1e9)) if lag > 0 else None
        """Instants held back before they are published (``publish_lag_s``)."""
        self.ptz_answers: list[PtzAnswer] = []
        """Answers to the batches' PTZ requests, for the shell to reply and clear."""

    # -- inputs ---------------------------------------------------------------
    def absorb(self, batch: Batch) -> None:
        """File a batch of messages without running a tick."""
        for info in batch.infos:
            self.schedule.declare(info.sensor_id, info.fps)
            self.poses.update_info(info)
            self.ptz.update_info(info)
        # Sensors that came first, their frames next, sensors that went last: the frames a batch holds arrived
        # before the liveliness change that ends it (a node stops publishing, then its token goes).
        for sid, alive in batch.presence.items():
            if alive:
                if sid not in self.present and len(self.present) >= 4 * MAX_SENSORS:
                    # Bounded memory under liveliness churn: forget sensors already gone first.
                    for gone in [k for k, v in self.present.items() if not v]:
                        del self.present[gone]
                    if len(self.present) >= 4 * MAX_SENSORS:
                        continue
                self.present[sid] = True
        for f in batch.features:  # in arrival order: the buffers sort, and count what came out of order
            sid = f.sensor_id
            if not self.present.get(sid, True) or (
                sid not in self.ingest.buffers and len(self.ingest.buffers) >= MAX_SENSORS
            ):
                # A frame of a sensor gone before this batch; or bounded memory: ids nobody announced cannot grow
                # the buffers without limit.
                self.ingest.counters.dropped += 1
                continue
            kind = self.ingest.add(f)
            processing_ns = int(f.processing_ms * 1e6)
            arrival = batch.received_ns or f.stamp_ns + processing_ns
            self.schedule.arrived(sid, f.stamp_ns, arrival, processing_ns, kind)
        for sid, alive in batch.presence.items():
            if not alive and (sid in self.present or sid in self.ingest.buffers or sid in self.poses.infos):
                self.present[sid] = False
                self.ingest.forget(sid)
                self.schedule.forget(sid)
                self.poses.forget(sid)
                self.ptz.forget(sid)
        for aid, alive in batch.agents.items():
            if not alive:
                self.ptz.agent_gone(aid)
        if batch.ptz_requests:
            targets = self.ptz_targets()
            for ask in batch.ptz_requests:
                self.ptz_answers.append(self.ptz.answer(ask, targets.get(ask.request.track_id)))

    # -- the tick -------------------------------------------------------------
    def step(self, batch: Batch, t_ns: int) -> TickResult:
        """Absorb ``batch`` and fuse at instant ``t_ns``."""
        self.absorb(batch)
        if t_ns <= self.last_t_ns:
            self.skipped_ticks += 1
            return self._result([], [], [], [], skipped=True)
        self.last_t_ns = t_ns
        self.ingest.last_fusion_ns = t_ns
        aligned: dict[str, AlignedView] = {}
        surveyed = self.poses.surveyed()
        # Mutual calibration matters only while some present sensor has no surveyed pose.
        need_sightings = self.poses.params.enabled and any(
            sid not in surveyed for sid in self.ingest.buffers if self.present.get(sid, True)
        )
        for sid, buf in self.ingest.buffers.items():
            if not self.present.get(sid, True):
                continue
            view = align_sensor(buf, sid, t_ns, self._align_params(sid), sightings=need_sightings)
            if view is not None:
                aligned[sid] = view
        states = self._detector_states(t_ns)
        # Only a camera whose own node reports motion may move (resource_manager/poses/solver.py).
        moving = [sid for sid, state in states.items() if state == "moving"]
        poses = self.poses.solve({sid: v.sightings for sid, v in aligned.items()}, t_ns, moving)
        self.last_poses = poses
        # A robot that moves, or has stopped but not settled (node relearning its background, pose converging),
        # gives no views: the tracks carry on with the other cameras (views/settling.py).
        positions = {sid: p.origin for sid, p in poses.items()}
        self.planner.note_arrivals(positions, t_ns)
        driving = self.planner.driving(positions, t_ns)
        unsettled = (
            self.trust.update(
                t_ns,
                poses,
                mobile=[sid for sid, info in self.poses.infos.items() if info.mobile],
                en_route=self.planner.en_route(positions) if self.planner.held else (),
                with_blobs=[sid for sid, v in aligned.items() if v.blobs],
                states=states,
            )
            if self.trust.params.enabled
            else frozenset()
        )
        seeing = {sid: v for sid, v in aligned.items() if sid not in unsettled}
        views = build_views(seeing, poses, self.poses.infos, self.poses.bearing_sigma, feet=self.feet)
        self.last_views = views
        outcome = self.tracker.step(
            views,
            t_ns,
            blind=frozenset() if self.trust.params.enabled else driving,
            pose_sigma={sid: p.sigma_xy_m for sid, p in poses.items()},
        )
        ended = outcome.ended
        self.ingest.trim(t_ns - self.align_params.stale_ns)
        old_ns = t_ns - 2 * self.align_params.stale_ns
        for sid, buf in list(self.ingest.buffers.items()):
            newest = buf.newest_stamp()
            if sid not in self.poses.infos and not self.present.get(sid) and (newest is None or newest < old_ns):
                self.ingest.forget(sid)  # a stale sensor that never said what it is: free its slot
                self.schedule.forget(sid)
        plans = self._plans(t_ns, poses)
        commands = self._ptz_commands(t_ns)
        return self._result(outcome.pair_entries, plans, commands, ended, in_use=sorted(views), aligned=aligned)

    def _align_params(self, sid: str) -> AlignParams:
        """The alignment limits for one sensor: the config's, widened to its frame period (a 2 fps camera's
        frames are 500 ms apart: they are interpolated between, and a frame missing between two is tolerated)."""
        info = self.poses.infos.get(sid)
        p = self.align_params
        if info is None or info.fps <= 0:
            return p
        period = 1e9 / info.fps
        return AlignParams(
            max_extrapolation_ns=max(p.max_extrapolation_ns, int(HOLD_PERIODS * period)),
            stale_ns=max(p.stale_ns, int(STALE_PERIODS * period)),
            max_gap_ns=max(p.max_gap_ns, int(GAP_PERIODS * period)),
        )

    def known_sensors(self) -> list[str]:
        """Every sensor heard of: by its SensorInfo, its frames, or a pose override."""
        return sorted(set(self.ingest.buffers) | set(self.poses.infos) | set(self.poses.overrides))

    def _in_use(self) -> list[str]:
        """The sensors the watermark waits for: present ones with frames, and declared ones whose first frame is
        still to come."""
        with_frames = {sid for sid, buf in self.ingest.buffers.items() if buf.newest_stamp() is not None}
        return [sid for sid in sorted(with_frames | self.poses.infos.keys()) if self.present.get(sid, True)]

    def next_instant(self, now_ns: int) -> int | None:
        """The instant to fuse now by the watermark rule (:mod:`resource_manager.ingest.schedule`), or None while
        nothing new can be fused. Call after :meth:`absorb` has filed what arrived."""
        return self.schedule.instant(self._in_use(), now_ns, self.last_t_ns)

    def until_due_ns(self, now_ns: int) -> int | None:
        """How long until an instant may be due with no new frame (a sensor's deadline passing); None: only a
        new frame can make one due."""
        return self.schedule.until_due_ns(self._in_use(), now_ns, self.last_t_ns)

    def _detector_states(self, t_ns: int) -> dict[str, DetectorState]:
        """Sensors whose frames around ``t_ns`` say their detector cannot see ("learning", "moving")."""
        out: dict[str, DetectorState] = {}
        for sid, buf in self.ingest.buffers.items():
            for f in buf.bracket(t_ns):
                if f is not None and f.state != "ok" and out.get(sid) != "moving":
                    out[sid] = f.state
        return out

    # -- outputs --------------------------------------------------------------
    def published_tracks(self) -> list[TrackSnapshot]:
        """The tracks a TrackSet reports (:attr:`TrackSnapshot.reported`); tentative ones too with
        ``publish_tentative``."""
        show_tentative = self.config.manager.publish_tentative
        return [tr for tr in self.tracker.snapshots() if tr.reported or (show_tentative and not tr.confirmed)]

    def track_message(self, tr: TrackSnapshot, track_id: str = "", seq: int = -1) -> Track:
        """The message of one track (``track_id``: the id to publish it under, default its own; ``seq``: of the
        TrackSet it goes out in, default the current one). A track published under an id it was confirmed with
        later (``publish_lag_s``) is published as confirmed then."""
        tid = track_id or tr.track_id or f"{self.manager_id}-t{tr.serial}"
        state = tr.state
        if track_id and state == "tentative":
            state = "confirmed" if tr.detected else "coasting"
        x, y, vx, vy = tr.x.tolist()[:4]  # plain floats: np.clip on scalars costs ~10x
        (pxx, pxy), (_, pyy) = tr.p_xy.tolist()
        return Track(
            manager_id=self.manager_id,
            seq=self.seq if seq < 0 else seq,
            stamp_ns=tr.t_ns,
            track_id=tid,
            x_m=_clip(x, -1e5, 1e5),
            y_m=_clip(y, -1e5, 1e5),
            height_m=_clip(tr.height_m, 0.0, 1e5),
            vx_mps=_clip(vx, -1e3, 1e3),
            vy_mps=_clip(vy, -1e3, 1e3),
            cov_xx_m2=_clip(pxx, 0.0, 1e10),
            cov_xy_m2=_clip(pxy, -1e10, 1e10),
            cov_yy_m2=_clip(pyy, 0.0, 1e10),
            state=state,
            method=tr.method,
            sensors=list(tr.sensors)[:64],
            predicted_error_m=_clip(tr.predicted_error_m, 0.0, 1e5),
            age_s=max(0.0, (tr.t_ns - tr.born_ns) / 1e9),
            hits=min(tr.hits, 2**31 - 1),
            misses=min(tr.misses, 2**31 - 1),
        )

    def live_tracks(self) -> list[Track]:
        """This instant's published tracks as messages (what goes out with no ``publish_lag_s``)."""
        return [self.track_message(tr) for tr in self.published_tracks()][:MAX_TRACKS]

    def lagged_set(self, instant: LaggedInstant) -> TrackSet:
        """The TrackSet of an instant held back by ``publish_lag_s``."""
        tracks = [self.track_message(tr, tid, instant.seq) for tr, tid in instant.tracks][:MAX_TRACKS]
        return TrackSet(
            manager_id=self.manager_id,
            seq=instant.seq,
            stamp_ns=instant.t_ns,
            tracks=tracks,
            sensors_used=instant.sensors_used[:64],
        )

    def flush(self) -> list[TrackSet]:
        """The TrackSets still held back by ``publish_lag_s`` (the end of a recorded run), oldest first."""
        return [self.lagged_set(i) for i in self.lagged.flush()] if self.lagged is not None else []

    def ptz_targets(self) -> dict[str, PtzTarget]:
        return {
            tr.track_id: PtzTarget(tr.track_id, float(tr.x[0]), float(tr.x[1]), tr.height_m)
            for tr in self.tracker.snapshots()
            if tr.track_id
        }

    def _plans(self, t_ns: int, poses: dict[str, PoseEstimate]) -> list[ViewPlan]:
        infos = self.poses.infos
        if not any(sid in infos and infos[sid].mobile for sid in poses):
            return []  # no mobile camera: nothing to plan (checked before building the cameras)
        cams = [
            replace(
                plan_camera(sid, pose.origin, pose.z_m, infos.get(sid), self.poses.bearing_sigma(sid)),
                ranged=pose.source == "mutual",
            )
            for sid, pose in poses.items()
        ]
        targets = [
            PlanTarget(
                tr.track_id,
                tr.xy.copy(),
                tr.predicted_error_m,
                tr.sensors,
                tr.height_m if tr.height_m > 0 else HEAD_HEIGHT_M,
            )
            for tr in self.tracker.snapshots()
            if tr.track_id and tr.state == "confirmed"
        ]
        out = []
        for g in self.planner.plan(t_ns, cams, targets):
            self.plan_seq += 1
            out.append(
                ViewPlan(
                    manager_id=self.manager_id,
                    seq=self.plan_seq,
                    stamp_ns=t_ns,
                    sensor_id=g.sensor_id,
                    partner_id=g.partner_id,
                    track_id=g.track_id,
                    goal_x_m=g.goal_xy[0],
                    goal_y_m=g.goal_xy[1],
                    baseline_m=g.baseline_m,
                    phi1_rad=min(max(g.phi1_rad, 0.0), 2 * math.pi),
                    predicted_error_m=g.predicted_error_m,
                    current_error_m=g.current_error_m,
                )
            )
        return out

    def _ptz_commands(self, t_ns: int) -> list[PtzCommand]:
        out = []
        for aim in self.ptz.tick(self.ptz_targets(), t_ns):
            self.ptz_seq += 1
            out.append(
                PtzCommand(
                    manager_id=self.manager_id,
                    seq=self.ptz_seq,
                    stamp_ns=t_ns,
                    sensor_id=aim.sensor_id,
                    pan_rad=float(wrap_angle(aim.pan_rad)),
                    tilt_rad=float(np.clip(aim.tilt_rad, -math.pi / 2, math.pi / 2)),
                    zoom=float(aim.zoom),
                    track_id=aim.track_id,
                )
            )
        return out

    def _result(
        self,
        pair_entries: list[PairEntry],
        plans: list[ViewPlan],
        commands: list[PtzCommand],
        ended: list[str],
        *,
        skipped: bool = False,
        in_use: list[str] | None = None,
        aligned: Mapping[str, AlignedView] | None = None,
    ) -> TickResult:
        if not skipped:
            self.seq += 1
        used = sorted(in_use or [])
        trackset: TrackSet | None = None
        if self.lagged is None:
            trackset = TrackSet(
                manager_id=self.manager_id,
                seq=self.seq,
                stamp_ns=self.last_t_ns,
                tracks=self.live_tracks(),
                sensors_used=used[:64],
            )
        elif not skipped:
            self.lagged.push(self.seq, self.last_t_ns, used, self.tracker.snapshots())
            due = self.lagged.due(self.last_t_ns)
            trackset = self.lagged_set(due) if due is not None else None
        known = self.known_sensors()
        without = sorted(s for s in (aligned or {}) if s not in self.last_poses)
        c = self.ingest.counters
        counters = TickCounters(
            sensors_in_use=used,
            sensors_known=known,
            sensors_without_pose=without,
            late=c.late,
            duplicate=c.duplicate,
            out_of_order=c.out_of_order,
            dropped=c.dropped,
            clock_steps=c.clock_steps,
            skipped_ticks=self.skipped_ticks,
            sensors_absent=sorted(sid for sid, alive in self.present.items() if not alive),
            poses=tuple(self.last_poses[sid] for sid in sorted(self.last_poses)),
        )
        result = TickResult(
            trackset=trackset,
            pair_choice=PairChoice(
                manager_id=self.manager_id, seq=self.seq, stamp_ns=self.last_t_ns, choices=pair_entries[:MAX_TRACKS]
            ),
            plans=plans,
            ptz_commands=commands,
            counters=counters,
            ended=ended,
            skipped=skipped,
        )
        self.last_result = result
        return result
