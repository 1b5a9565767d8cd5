"""The resource manager's configuration: one TOML file per manager process.

Example (``deploy/nodes/examples/manager.toml`` is the annotated full version)::

    [manager]
    id = "mgr1"
    prefix = "pano"
    rate_hz = 10.0
    latency_ms = 200.0
    matcher = "greedy"          # or "global"
    fuse_all = false
    state_dir = "state/mgr1"

    [zenoh]
    connect = ["tcp/127.0.0.1:7447"]

    [clock]
    ntp_server = ""

    [[pose]]                    # optional surveyed-pose overrides
    id = "pano1"
    x_m = 0.0
    y_m = 0.0
    z_m = 1.1
    yaw_deg = 0.0

Every table but ``[manager]`` is optional. Unknown keys are errors.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Literal

import msgspec

from common.clock import ClockSettings
from common.config import ConfigStruct, load_config, resolve_path
from common.errors import ConfigError
from common.keys import DEFAULT_PREFIX, Keys, validate_id
from common.session import SessionSettings

__all__ = [
    "ManagerConfig",
    "ManagerSection",
    "MatchSection",
    "MutualSection",
    "PlannerSection",
    "PoseOverride",
    "PtzSection",
    "TrackerSection",
    "load_manager_config",
]

Pos = Annotated[float, msgspec.Meta(gt=0.0)]
NonNeg = Annotated[float, msgspec.Meta(ge=0.0)]
Frac = Annotated[float, msgspec.Meta(ge=0.0, le=1.0)]
PosInt = Annotated[int, msgspec.Meta(ge=1)]


class ManagerSection(ConfigStruct, frozen=True):
    """``[manager]``: identity, tick rate, time alignment, persistence."""

    id: str
    """Manager id; track ids are ``{id}-{n}``."""
    prefix: str = DEFAULT_PREFIX
    rate_hz: Annotated[float, msgspec.Meta(gt=0.0, le=200.0)] = 10.0
    """Fusion ticks per second."""
    latency_ms: Annotated[float, msgspec.Meta(ge=0.0, le=10_000.0)] = 200.0
    """The fusion instant is ``now - latency``: larger than a frame period plus the network delay, so that
    two frames of every sensor bracket it. Raising it adds delay; lowering it forces extrapolation."""
    max_extrapolation_ms: NonNeg = 100.0
    """Furthest a blob is extrapolated (or held) past its nearest frame; beyond it the sensor sits out the tick."""
    stale_ms: Pos = 1000.0
    """A sensor whose newest frame is older than this before the fusion instant is left out."""
    max_gap_ms: Pos = 500.0
    """Two frames further apart than this are not interpolated between (the nearer one is held instead)."""
    buffer_frames: PosInt = 64
    """Most frames kept per sensor (bounded memory)."""
    clock_step_ms: Pos = 1500.0
    """A frame this much older than the newest with a higher seq is a sender clock step: the buffer restarts."""
    matcher: Literal["greedy", "global"] = "greedy"
    """Stereo matcher by registry name: ``greedy`` (the paper's, O(N^3/3)) or ``global`` (Hungarian)."""
    fuse_all: bool = False
    """False: localise each person with the best pair only (the paper). True: least squares over every view."""
    publish_tentative: bool = False
    """Also publish tracks still waiting for birth confirmation."""
    state_dir: str = ""
    """Where the track log and id counter persist (relative to the config file); "" = ``state/{id}``."""
    history_s: Pos = 600.0
    """How much track history is kept in memory, reloaded at start and served by ``?history=``."""
    history_hz: Pos = 5.0
    """States per track kept in the history (and its log) per second; the live stream is every tick."""
    segment_s: Pos = 60.0
    """Length of one track-log segment file."""
    retain_s: Pos = 3600.0
    """Track-log segments older than this are deleted."""
    status_period_s: Pos = 1.0
    default_bearing_sigma_deg: Pos = 0.2
    """Bearing error of a sensor whose SensorInfo has not arrived."""
    sensors: list[str] = []
    """The sensor ids this manager fuses; every other sensor's messages are refused by key, before decoding,
    and counted (ManagerStatus.refused). Empty: the sensors of its site (``--site FILE``, which ``panostereo up``
    and ``demo`` pass); a manager with neither refuses to start. ``["*"]``: any sensor (a lab bench only: any
    client, or a stray camera sharing the router, then feeds the tracks)."""
    max_skew_s: Annotated[float, msgspec.Meta(gt=0.0, le=86_400.0)] = 1.5
    """Features stamped further than this from the manager's NTP-corrected clock are refused (counted per sensor
    as clock skew) and never buffered: a frame from the future would become the sensor's newest, one from long
    ago restart its buffer. An honest frame is at most ``latency_ms`` plus its node's processing and network delay
    old (older than ``latency_ms + stale_ms`` it is useless anyway) and never ahead by more than the hosts' NTP
    error. Raise it only for a node known to lag more; below ``latency_ms`` plus the delays it refuses real
    frames."""
    max_lead_s: Annotated[float, msgspec.Meta(ge=0.0, le=86_400.0)] = 0.25
    """...and those stamped more than this *ahead* of it: nothing is captured in the future, so this is only the
    hosts' NTP error (ms on a LAN). Forged frames stamped just ahead would stand in for the real ones in
    alignment for that long after a flood stops."""
    info_refresh_s: Annotated[float, msgspec.Meta(ge=0.2, le=3600.0)] = 2.0
    """Each sensor's SensorInfo is re-read from its own queryable this often (and when its liveliness token
    comes back): anything put under its id by another client is replaced within this long. A put that changes
    a SensorInfo is never taken as such, only a reason to read it again."""


class PoseOverride(ConfigStruct, frozen=True):
    """``[[pose]]``: a surveyed pose that overrides what the sensor reports."""

    id: str
    x_m: float
    y_m: float
    z_m: float
    yaw_deg: float = 0.0


class MatchSection(ConfigStruct, frozen=True):
    """``[match]``: Eq. (7) measures and thresholds."""

    threshold: Frac = 0.2
    """tau: a pair is accepted only if its confidence exceeds this (raise: fewer, surer matches). With colour
    the wrong pair of two people walking side by side scores ~0.1-0.2 (r_is); much higher and far people's
    real pairs are refused (synthetic 4 cameras x 6 people: MOTA 0.84 at 0.1, 0.89 at 0.2; 16 x 20: 0.97 at
    0.1, 0.99 at 0.2, 0.95 at 0.25). Without colour (detection files, r_is = 1) 0.1."""
    temporal_weight: NonNeg = 1.0
    """lambda in r' = (r + lambda c_t)/(1 + lambda); 0 disables the temporal term."""
    temporal_gate_m: NonNeg = 0.6
    """Distance from a track's prediction at which the positional temporal term has fallen to exp(-1/2): a
    hypothesis near a track continues it even when the nodes' 2D ids changed. 0: ids only (measured: 16 cameras
    x 20 people MOTA 0.99 vs 0.95 without; Wildtrack 0.645 vs 0.62; one demo recording 0.86 vs 0.90)."""
    max_range_m: Pos = 30.0
    """r_rc = 0 when a hypothesised target lies further than this from either camera."""
    width_sigma: Pos = 0.35
    """Spread of ln(W1/W2) in r_wc (frontal vs side widths differ by ~0.6)."""
    floor_sigma_m: NonNeg = 0.25
    """Part of r_hc: where a blob's feet are visible, z_cam + D tan(bottom) must be the floor within this
    (plus the bearing error times D); 0 disables. Ghosts of crossing rays stand above or below the floor."""
    width_floor: Frac = 0.0
    """Smallest r_wc: raise it (e.g. 0.3) when the nodes merge occluding people into one wide blob."""
    height_sigma: Pos = 0.12
    """Spread of ln(H1/H2) in r_hc."""
    use_colour: bool = True
    """False: r_is = 1 (e.g. detection files without colour)."""
    width_rel_sigma: Pos = 0.1
    """Relative width error epsilon fed to the size-ratio crossover."""
    look_weight: NonNeg = 0.0
    """Per camera, a blob's colour dissimilarity (1 - Bhattacharyya) to a track's running look in that view
    times this is added to the support assignment cost (gate units squared): people who meet keep their own
    blobs. 0: position (and node ids) only."""
    fix_look_min: Frac = 0.0
    """A fix whose two blobs match the track's running looks in those views worse than this (mean Bhattacharyya
    coefficient) is someone else's: two other people's rays, or the neighbour's blob after a merge (0: off;
    needs ``look_weight`` > 0, which keeps the looks)."""
    bearing_gate_sigmas: Pos = 4.0
    """A blob supports a track when its bearing is within this many sigmas of the predicted bearing."""
    link_gate_m: Pos = 1.0
    """A measurement outside the motion gate is still taken when both blobs continue the track's node-side
    2D tracks (same local ids) and it lies within this distance of the prediction (sharp turns)."""
    bearing_updates: bool = False
    """When no pair localises a track, the cameras that still follow it update it by bearing alone (EKF)."""
    max_birth_pairs: PosInt = 12
    """Most camera pairs matched per tick only to find new people (bounds the cost with many cameras)."""
    pair_choice: Literal["error_model", "random"] = "error_model"
    """How the localising pair is chosen: by the error model (the paper), or at random among the cameras that
    see the person (a baseline to compare against)."""
    pair_reuse_tolerance: Annotated[float, msgspec.Meta(ge=1.0, le=10.0)] = 1.5
    """A camera pair already matched this tick is used when its predicted error is within this factor of the
    best pair's (1.0: always the best pair; raising it saves Eq. 7 matrices with many cameras)."""
    max_pair_cameras: Annotated[int, msgspec.Meta(ge=2, le=64)] = 5
    """Only the cameras nearest a person are paired when ranking pairs (5 cameras: 10 pairs)."""
    ghost_veto_views: PosInt = 1
    mono_elev_sigma_deg: NonNeg = 0.1
    """Feet-elevation error of fixed perspective cameras (SensorInfo kind ``pinhole``, e.g. detection files):
    their blobs' feet give floor distances (resource_manager/mono.py) that gate support, veto ghosts and
    keep tracks when no pair localises them. 0 disables; raise it for noisy box bottoms."""
    mono_base_sigma_m: NonNeg = 0.1
    """Added to every floor-distance sigma (the feet are not exactly below the head)."""
    mono_gate_sigmas: Pos = 3.0
    """A fix or a birth whose distance from a camera disagrees with that blob's feet by more than this many
    sigmas is a ghost (lower: stricter)."""
    mono_updates: bool = True
    """When no pair localises a track, its views' floor points (fused) update it."""
    shared_pairs: bool = False
    """A track whose person is hidden behind a neighbour in some views (one blob there explains both) is
    localised by pairing its own blobs with those shared blobs when no pair of its own does."""
    room_margin_m: NonNeg = 0.5
    """A fix or a new person further than this outside ``[planner] room`` (when given) is refused: nobody stands
    outside the room (near-colinear cameras put fixes far along the ray)."""
    group_coast_s: Annotated[float, msgspec.Meta(ge=0.0, le=30.0)] = 0.0
    """A confirmed track with no stereo fix, one camera of its own and blobs it shares with neighbours elsewhere
    (a merged group) is fixed from its own ray and those blobs' extents (resource_manager/group.py) for at most
    this long after its last stereo fix (0: off; it coasts and may die while its group stays merged)."""
    min_view_agreement: Frac = 0.8
    """With 3+ cameras in range, a position (new or measured) needs a blob toward it in this fraction of them
    (a person is seen by nearly all, or hidden behind someone who is; a ghost of crossing rays is not). A confirmed
    track's fix that 3+ of its own cameras point at, none elsewhere, is taken whatever the others see."""
    """A new person is refused when this many other cameras that should see the spot see nothing there."""


class TrackerSection(ConfigStruct, frozen=True):
    """``[tracker]``: the constant-velocity Kalman filter and the track life cycle."""

    accel_sigma_mps2: Pos = 3.0
    """Process noise: raising it follows turns faster, lowering it smooths more."""
    gate_chi2: Pos = 13.8
    """Mahalanobis gate on the floor (chi-square, 2 dof; 13.8 ~ 99.9%)."""
    gate_min_m: Pos = 0.3
    """Measurements within this distance always pass the gate."""
    min_meas_sigma_m: Pos = 0.03
    birth_hits: PosInt = 3
    """Consistent measurements needed before a track is confirmed."""
    birth_window: PosInt = 5
    """...within this many ticks."""
    max_misses: PosInt = 15
    """A confirmed track dies after this many ticks without a measurement."""
    init_speed_sigma_mps: Pos = 1.0
    height_alpha: Frac = 0.2
    """Smoothing of the head height (EMA weight of a new measurement)."""
    max_speed_mps: Pos = 3.0
    """Velocity estimates are clamped to this: a walking person; a larger value is a jump between people."""
    max_gate_m: Pos = 1e9
    """Cap of the gate radius: a coasting track's covariance grows each tick it misses, and past about the
    spacing of two people its gate reaches the neighbour's fixes."""
    coast_damping_s: Pos = 1e9
    """Time constant (s) of the velocity decay of a coasting track (1e9: constant velocity)."""
    relink_s: Annotated[float, msgspec.Meta(ge=0.0, le=60.0)] = 0.0
    """A track lost after ``max_misses`` is held (unpublished) this long; a new track confirmed near where it
    was lost takes its id instead of a new one. 0: off (a lost track ends at once)."""
    relink_m: Pos = 1.0
    """...near: within this distance (plus 0.5 m per second since it was lost) and 0.15 m of head height."""


class MutualSection(ConfigStruct, frozen=True):
    """``[mutual]``: mutual calibration (Eq. 3) of mobile panoramic cameras."""

    enabled: bool = True
    smoothing_s: Pos = 1.0
    """Time constant of the pose smoothing (raise: steadier but lags a moving robot)."""
    timeout_s: Pos = 2.0
    """A calibrated pose not refreshed for this long becomes unknown again."""
    jump_m: Pos = 1.0
    """A new pose further than this from the smoothed one restarts the smoothing."""
    boundary_sigma_deg: NonNeg = 0.0
    """Error of one occluding-boundary bearing; 0 = the observer's bearing sigma."""
    default_height_m: Pos = 1.1
    """Camera height of a mobile sensor whose SensorInfo carries no pose with z_m."""


class PlannerSection(ConfigStruct, frozen=True):
    """``[planner]``: view planning of mobile cameras (Eqs. 4-6, Fig. 4)."""

    enabled: bool = True
    period_s: Pos = 0.5
    room: list[float] = []
    """``[x_min, y_min, x_max, y_max]`` the goals are clipped to; empty = no bounds."""
    margin_m: NonNeg = 0.4
    min_move_m: NonNeg = 0.15
    """A new goal closer than this to the previous one is not re-issued."""
    gain_frac: Annotated[float, msgspec.Meta(ge=0.0, lt=1.0)] = 0.25
    """Hysteresis: a new goal only when its predicted error is below (1 - gain_frac) of the held goal's."""
    settle_s: NonNeg = 4.0
    """A new goal (and the first one) waits this long after the previous one, unless that became infeasible."""
    min_gain_m: NonNeg = 0.05
    """...and the predicted error must fall by at least this much (a move costs the robot's detections)."""
    band_z_m: NonNeg = 0.62
    """Height of the robots' marking band (upper part; minimum baseline: bands above the lower elevation limit)."""
    elev_margin_deg: NonNeg = 1.0
    """Margin inside the lens' elevation limits for bands and heads."""
    min_band_px: Pos = 12.0
    """Maximum baseline: the ranged body at least this many pixels wide."""
    keep_m: NonNeg = 0.8
    """Clearance from people on the drive and at the goal."""
    found_m: NonNeg = 0.5
    """Cost of moving: a person counts as found within this (CLEAR-MOT's match distance); where nobody else can
    pair the people a robot helps, it moves only when the found person-seconds gained over ``horizon_s`` exceed
    those lost while it drives and settles (resource_manager/plan/checks.py). 0: moves cost nothing."""
    horizon_s: Pos = 15.0
    """How long a new viewpoint is counted on, from when the robot has settled there."""
    speed_mps: Pos = 0.4
    """The robots' driving speed, for the time a move takes."""
    settle_views: bool = True
    """Leave out the views of a camera whose node cannot see (Features.state) and of a robot that moved, until it
    has stopped, relearnt its background and its pose has converged (resource_manager/settling.py)."""


class PtzSection(ConfigStruct, frozen=True):
    """``[ptz]``: PTZ allocation to user agents."""

    max_range_m: Pos = 25.0
    aim_height_frac: Frac = 0.85
    """Aim at this fraction of the person's height (0.85: the face)."""
    target_width_m: Pos = 1.5
    """Zoom so that about this much of the scene fills the image width."""
    hfov_deg: Annotated[float, msgspec.Meta(gt=1.0, lt=170.0)] = 60.0
    """Horizontal field of view at zoom 1 (for the zoom command)."""
    max_zoom: Annotated[float, msgspec.Meta(ge=1.0, le=1000.0)] = 10.0
    min_tilt_deg: float = -80.0
    max_tilt_deg: float = 60.0
    lease_s: Annotated[float, msgspec.Meta(gt=0.0, le=86_400.0)] = 30.0
    """A PTZ hold ends this long after the agent's last request for it unless renewed (an agent that keeps a
    view asks again every third of it), and at once when the agent's liveliness token goes. A request may ask
    for a shorter lease, never a longer one."""


class ManagerConfig(ConfigStruct, frozen=True):
    """The whole manager config file."""

    manager: ManagerSection
    zenoh: SessionSettings = msgspec.field(default_factory=SessionSettings)
    clock: ClockSettings = msgspec.field(default_factory=ClockSettings)
    match: MatchSection = msgspec.field(default_factory=MatchSection)
    tracker: TrackerSection = msgspec.field(default_factory=TrackerSection)
    mutual: MutualSection = msgspec.field(default_factory=MutualSection)
    planner: PlannerSection = msgspec.field(default_factory=PlannerSection)
    ptz: PtzSection = msgspec.field(default_factory=PtzSection)
    pose: list[PoseOverride] = []

    @property
    def keys(self) -> Keys:
        return Keys(self.manager.prefix)

    @property
    def default_bearing_sigma_rad(self) -> float:
        return math.radians(self.manager.default_bearing_sigma_deg)


def validate_manager_config(cfg: ManagerConfig, source: str) -> ManagerConfig:
    """Checks msgspec cannot express; raises ConfigError naming the key."""
    try:
        validate_id(cfg.manager.id, "manager.id")
        Keys(cfg.manager.prefix)
        for i, sid in enumerate(cfg.manager.sensors):
            if sid != "*":
                validate_id(sid, f"manager.sensors[{i}]")
        for i, p in enumerate(cfg.pose):
            validate_id(p.id, f"pose[{i}].id")
    except ConfigError as err:
        raise ConfigError(f"{source}: {err}") from err
    room = cfg.planner.room
    if room and (len(room) != 4 or room[0] >= room[2] or room[1] >= room[3]):
        raise ConfigError(f"{source}: planner.room must be [x_min, y_min, x_max, y_max], got {cfg.planner.room!r}")
    if "*" in cfg.manager.sensors and len(cfg.manager.sensors) > 1:
        raise ConfigError(
            f'{source}: manager.sensors is either ["*"] (any sensor) or a list of ids, got {cfg.manager.sensors!r}'
        )
    ids = [p.id for p in cfg.pose]
    if len(set(ids)) != len(ids):
        raise ConfigError(f"{source}: pose ids must be unique, got {ids!r}")
    if cfg.tracker.birth_hits > cfg.tracker.birth_window:
        raise ConfigError(
            f"{source}: tracker.birth_hits ({cfg.tracker.birth_hits}) must be <= tracker.birth_window "
            f"({cfg.tracker.birth_window})"
        )
    return cfg


def load_manager_config(path: str | Path) -> ManagerConfig:
    """Load and validate a manager config; ``state_dir`` is resolved relative to the file.

    Raises:
        ConfigError: naming the file, the key, what was expected and what was given.
    """
    cfg = load_config(path, ManagerConfig)
    cfg = validate_manager_config(cfg, str(path))
    state = cfg.manager.state_dir or f"state/{cfg.manager.id}"
    resolved = str(resolve_path(path, state))
    return msgspec.structs.replace(cfg, manager=msgspec.structs.replace(cfg.manager, state_dir=resolved))
