"""The manager's whole per-tick computation, pure: received messages in, tracks and commands out.

``Fusion(config).absorb(batch)`` files what arrived in the sensor registry (:mod:`~resource_manager.sensors`:
SensorInfo, presence, bounded frame buffers with late, duplicate and out-of-order frames counted, frame timing) and
answers PTZ requests; ``step(t_ns)`` then runs, at the fusion instant ``t_ns``, in the paper's order:

1. align every sensor's blobs to ``t_ns`` by NTP stamps and interpolation (:mod:`~resource_manager.ingest`);
2. poses: surveyed ones plus mutual calibration, Eq. (3) (:mod:`~resource_manager.poses`);
3. views: every camera's blobs in world terms, and which cameras can see now (:mod:`~resource_manager.views`);
4. track: per view, blobs assigned to the predicted tracks; each track updated with its views, new people
   paired across views by Eq. (7) and the error model, existence and life cycle (:mod:`~resource_manager.track`,
   which uses :mod:`~resource_manager.stereo` for Eqs. 1, 2, 7 and the pair ranking);
5. view plans for mobile cameras (Eqs. 4-6, :mod:`~resource_manager.plan`) and PTZ pointing
   (:mod:`~resource_manager.serve`).

Each call returns everything the shell sends (:class:`Absorbed`, :class:`TickResult`), the messages built by
:mod:`resource_manager.serve.messages`. No zenoh, no disk: tests and benchmarks feed it recorded or synthetic
messages; :mod:`resource_manager.node` is the thin shell around it.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace

from common.schema import (
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
from resource_manager.ingest.align import Aligned, AlignParams, align
from resource_manager.ingest.schedule import TickLatency
from resource_manager.plan.scene import PlanTarget, plan_camera
from resource_manager.poses.solver import PoseEstimate
from resource_manager.serve import messages
from resource_manager.serve.adopt import adopt_ids, follows
from resource_manager.serve.lag import LaggedTracks
from resource_manager.serve.ptz import Assignment, PtzAnswer, PtzAsk, PtzTarget
from resource_manager.track.tracker import TrackSnapshot
from resource_manager.views.blobs import Views
from resource_manager.views.build import build_views

__all__ = ["Absorbed", "Batch", "Fusion", "TickCounters", "TickResult"]

HOLD_PERIODS = 0.6
"""A sensor's blobs are held or extrapolated at most this many of its frame periods past its nearest frame."""
INTERPOLATE_PERIODS = 2.5
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
    """PTZ requests, answered when the batch is absorbed (:attr:`Absorbed.ptz_answers`): the allocation changes on
    one thread."""
    agents: Mapping[str, bool] = field(default_factory=dict)
    """Liveliness changes of user agents: agent id -> alive (a gone agent's PTZ holds end)."""
    received_ns: int = 0
    """When these features arrived (the manager's clock); 0: each at its own capture stamp plus its node's
    processing (dataset time)."""


@dataclass(frozen=True, slots=True)
class Absorbed:
    """What filing a batch gives the shell to send: PTZ answers, and the holds that ended."""

    ptz_answers: list[PtzAnswer] = field(default_factory=list)
    """Answers to the batch's PTZ requests, in order."""
    ptz_ended: list[tuple[Assignment, str]] = field(default_factory=list)
    """PTZ holds ended by the batch (an agent or a camera gone, a release, a preemption), with the reason."""


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
    """Everything one fused instant gives the shell to publish."""

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
    people: list[TrackSnapshot] = field(default_factory=list)
    """This instant's published tracks (``trackset``'s without ``publish_lag_s``) as the tracker holds them, each
    with the cameras whose blobs placed it (read by the cameras' agreement check, poses/agreement.py)."""
    views: Views = field(default_factory=Views.empty)
    """The views fused at this instant (read by the cameras' agreement check, poses/agreement.py)."""
    ptz_ended: list[tuple[Assignment, str]] = field(default_factory=list)
    """PTZ holds ended at this instant (a lease run out, a track ended), with the reason."""
    latency: TickLatency | None = None
    """Where the capture -> fusion time of this instant went (None: not an instant the scheduler chose)."""
    sightings_refused: dict[str, int] = field(default_factory=dict)
    """Sender id -> its sightings of other cameras the pose solver refused at this instant (ManagerStatus)."""


def _counter_ids(prefix: str) -> Callable[[], str]:
    n = itertools.count(1)
    return lambda: f"{prefix}-{next(n)}"


class Fusion:
    """The resource manager's state and its per-tick pipeline: :meth:`absorb` what arrived, then :meth:`step` to
    an instant.

    Args:
        config: the manager config.
        new_id: returns the next unique track id (default: an in-memory counter;
            the node passes the persisted allocator of :mod:`resource_manager.serve.history`).
    """

    def __init__(self, config: ManagerConfig, new_id: Callable[[], str] | None = None) -> None:
        self.config = config
        m = config.manager
        self.manager_id = m.id
        self.sensors = wiring.sensor_registry(config)
        self.align_params = wiring.align_params(config)
        self.schedule = wiring.schedule(config, self.sensors)
        self.poses = wiring.pose_solver(config, self.sensors)
        self.tracker = wiring.tracker(config, new_id or _counter_ids(m.id))
        self.feet = wiring.feet_model(config)
        self.planner = wiring.view_planner(config)
        self.trust = wiring.view_trust(config)
        self.ptz = wiring.ptz_allocator(config, self.sensors)
        self.last_t_ns = 0
        self.seq = 0
        self.plan_seq = 0
        self.ptz_seq = 0
        self.skipped_ticks = 0
        self.last_poses: dict[str, PoseEstimate] = {}
        lag = m.publish_lag_s
        self.lagged = LaggedTracks(int(lag * 1e9)) if lag > 0 else None
        """Instants held back before they are published (``publish_lag_s``)."""

    # -- inputs ---------------------------------------------------------------
    def absorb(self, batch: Batch) -> Absorbed:
        """File a batch of messages; answer its PTZ requests."""
        for info in batch.infos:
            self.sensors.declare(info)
        # Sensors that came first, their frames next, sensors that went last: the frames a batch holds arrived
        # before the liveliness change that ends it (a node stops publishing, then its token goes).
        for sid, alive in batch.presence.items():
            if alive:
                self.sensors.came(sid)
        for f in batch.features:  # in arrival order: the buffers sort, and count what came out of order
            self.sensors.file(f, batch.received_ns)
        for sid, alive in batch.presence.items():
            if not alive and self.sensors.went(sid):
                self.poses.forget(sid)
                self.ptz.forget(sid)
        for aid, alive in batch.agents.items():
            if not alive:
                self.ptz.agent_gone(aid)
        answers: list[PtzAnswer] = []
        if batch.ptz_requests:
            targets = self.ptz_targets()
            answers = [self.ptz.answer(ask, targets.get(ask.request.track_id)) for ask in batch.ptz_requests]
        return Absorbed(answers, self.ptz.take_ended())

    # -- the tick -------------------------------------------------------------
    def step(self, t_ns: int) -> TickResult:
        """Fuse at instant ``t_ns`` what :meth:`absorb` has filed."""
        if t_ns <= self.last_t_ns:
            self.skipped_ticks += 1
            return self._result([], [], [], [], skipped=True)
        self.last_t_ns = t_ns
        self.sensors.fused(t_ns)
        aligned = self._align(t_ns)
        states = self._detector_states(t_ns)
        # Only a camera whose own node reports motion may move (resource_manager/poses/solver.py).
        moving = [sid for sid, state in states.items() if state == "moving"]
        poses = self.poses.solve(aligned.sightings, t_ns, moving)
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
                mobile=[sid for sid, info in self.sensors.infos.items() if info.mobile],
                en_route=self.planner.en_route(positions) if self.planner.held else (),
                with_blobs=[sid for sid, n in zip(aligned.sensor_ids, aligned.counts.tolist(), strict=True) if n],
                states=states,
            )
            if self.trust.params.enabled
            else frozenset()
        )
        views = build_views(
            aligned,
            poses,
            self.sensors.infos,
            self.poses.bearing_sigma,
            feet=self.feet,
            point_sigma_m=self.config.tracker.body_sigma_m,
            skip=unsettled,
        )
        outcome = self.tracker.step(
            views,
            t_ns,
            blind=frozenset() if self.trust.params.enabled else driving,
            pose_sigma={sid: p.sigma_xy_m for sid, p in poses.items()},
        )
        stale_ns = self.align_params.stale_ns
        self.sensors.trim(t_ns - stale_ns, t_ns - 2 * stale_ns)
        plans = self._plans(t_ns, poses)
        commands = self._ptz_commands(t_ns)
        return self._result(
            outcome.pair_entries,
            plans,
            commands,
            outcome.ended,
            in_use=list(views.sensor_ids),
            aligned=aligned,
            views=views,
        )

    def _align(self, t_ns: int) -> Aligned:
        """Every present sensor's blobs (and, while some camera's pose is still to calibrate, sightings) at
        ``t_ns``."""
        surveyed = self.poses.surveyed()
        present = list(self.sensors.present_buffers())
        # Mutual calibration matters only while some present sensor has no surveyed pose.
        need_sightings = self.poses.params.enabled and any(sid not in surveyed for sid, _ in present)
        return align(((sid, buf, self._align_params(sid)) for sid, buf in present), t_ns, sightings=need_sightings)

    def _align_params(self, sid: str) -> AlignParams:
        """The alignment limits for one sensor: the config's, widened to its frame period (a 2 fps camera's
        frames are 500 ms apart: they are interpolated between, and a frame missing between two is tolerated)."""
        info = self.sensors.infos.get(sid)
        p = self.align_params
        if info is None or info.fps <= 0:
            return p
        period = 1e9 / info.fps
        return AlignParams(
            max_extrapolation_ns=max(p.max_extrapolation_ns, int(HOLD_PERIODS * period)),
            stale_ns=max(p.stale_ns, int(STALE_PERIODS * period)),
            max_gap_ns=max(p.max_gap_ns, int(INTERPOLATE_PERIODS * period)),
        )

    def known_sensors(self) -> list[str]:
        """Every sensor heard of: by its SensorInfo, its frames, or a pose override."""
        return self.sensors.known(set(self.poses.overrides))

    def next_instant(self, now_ns: int) -> int | None:
        """The instant to fuse now by the watermark rule (:mod:`resource_manager.ingest.schedule`), or None while
        nothing new can be fused. Call after :meth:`absorb` has filed what arrived."""
        return self.schedule.instant(self.sensors.in_use(), now_ns, self.last_t_ns)

    def until_due_ns(self, now_ns: int) -> int | None:
        """How long until an instant may be due with no new frame (a sensor's deadline passing); None: only a
        new frame can make one due."""
        return self.schedule.until_due_ns(self.sensors.in_use(), now_ns, self.last_t_ns)

    def _detector_states(self, t_ns: int) -> dict[str, DetectorState]:
        """Sensors whose frames around ``t_ns`` say their detector cannot see ("learning", "moving")."""
        out: dict[str, DetectorState] = {}
        for sid, buf in self.sensors.buffers.items():
            for f in buf.bracket(t_ns):
                if f is not None and f.state != "ok" and out.get(sid) != "moving":
                    out[sid] = f.state
        return out

    def adopt(self, theirs: Sequence[Track], keep: frozenset[str] = frozenset()) -> dict[int, str]:
        """Name the tracks after another manager's tracks of the same people (a standby after its leader's, a zone
        manager after its neighbours', :mod:`~resource_manager.serve.adopt`); returns the renames, serial -> id.

        ``keep``: ids this manager publishes itself: those tracks keep their ids, and no other takes them."""
        mine = [tr for tr in self.tracker.snapshots() if tr.track_id not in keep]
        followed = follows(mine, theirs)
        names = adopt_ids(mine, followed, taken=keep)
        self.tracker.adopt(names, followed)
        return names

    # -- outputs --------------------------------------------------------------
    def published_tracks(self) -> list[TrackSnapshot]:
        """The tracks a TrackSet reports (:attr:`TrackSnapshot.reported`); tentative ones too with
        ``publish_tentative``."""
        show_tentative = self.config.manager.publish_tentative
        return [tr for tr in self.tracker.snapshots() if tr.reported or (show_tentative and not tr.confirmed)]

    def live_tracks(self, shown: list[TrackSnapshot]) -> list[Track]:
        """This instant's published tracks (``shown``: :meth:`published_tracks`) as messages (what goes out with no
        ``publish_lag_s``)."""
        return [messages.track_message(self.manager_id, tr, self.seq) for tr in shown[:MAX_TRACKS]]

    def flush(self) -> list[TrackSet]:
        """The TrackSets still held back by ``publish_lag_s`` (the end of a recorded run), oldest first."""
        if self.lagged is None:
            return []
        return [messages.lagged_set(self.manager_id, i) for i in self.lagged.flush()]

    def _head_height(self, tr: TrackSnapshot) -> float:
        """A track's head-top height, or the prior's while none is known."""
        return tr.height_m if tr.height_m > 0 else self.config.tracker.height_prior_m

    def ptz_targets(self) -> dict[str, PtzTarget]:
        return {
            tr.track_id: PtzTarget(tr.track_id, float(tr.x[0]), float(tr.x[1]), self._head_height(tr))
            for tr in self.tracker.snapshots()
            if tr.track_id
        }

    def _plans(self, t_ns: int, poses: dict[str, PoseEstimate]) -> list[ViewPlan]:
        infos = self.sensors.infos
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
                self._head_height(tr),
            )
            for tr in self.tracker.snapshots()
            if tr.track_id and tr.state == "confirmed"
        ]
        out = []
        for g in self.planner.plan(t_ns, cams, targets):
            self.plan_seq += 1
            out.append(messages.view_plan(self.manager_id, self.plan_seq, t_ns, g))
        return out

    def _ptz_commands(self, t_ns: int) -> list[PtzCommand]:
        out = []
        # The tracks' places (a snapshot of every track) only where some camera is assigned to one.
        for aim in self.ptz.tick(self.ptz_targets() if self.ptz.assignments else {}, t_ns):
            self.ptz_seq += 1
            out.append(messages.ptz_command(self.manager_id, self.ptz_seq, t_ns, aim))
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
        aligned: Aligned | None = None,
        views: Views | None = None,
    ) -> TickResult:
        if not skipped:
            self.seq += 1
        used = sorted(in_use or [])
        trackset: TrackSet | None = None
        shown = self.published_tracks()[:MAX_TRACKS]
        if self.lagged is None:
            trackset = messages.track_set(self.manager_id, self.seq, self.last_t_ns, self.live_tracks(shown), used)
        elif not skipped:
            self.lagged.push(self.seq, self.last_t_ns, used, self.tracker.snapshots())
            due = self.lagged.due(self.last_t_ns)
            trackset = messages.lagged_set(self.manager_id, due) if due is not None else None
        c = self.sensors.counters
        counters = TickCounters(
            sensors_in_use=used,
            sensors_known=self.known_sensors(),
            sensors_without_pose=sorted(
                s for s in (aligned.sensor_ids if aligned is not None else ()) if s not in self.last_poses
            ),
            late=c.late,
            duplicate=c.duplicate,
            out_of_order=c.out_of_order,
            dropped=c.dropped,
            clock_steps=c.clock_steps,
            skipped_ticks=self.skipped_ticks,
            sensors_absent=self.sensors.absent(),
            poses=tuple(self.last_poses[sid] for sid in sorted(self.last_poses)),
        )
        return TickResult(
            trackset=trackset,
            pair_choice=messages.pair_choice(self.manager_id, self.seq, self.last_t_ns, pair_entries),
            plans=plans,
            ptz_commands=commands,
            counters=counters,
            ended=ended,
            skipped=skipped,
            people=shown,
            views=views if views is not None else Views.empty(),
            ptz_ended=self.ptz.take_ended(),
            latency=last if (last := self.schedule.last) is not None and last.t_ns == self.last_t_ns else None,
            sightings_refused=self.poses.take_refused(),
        )
