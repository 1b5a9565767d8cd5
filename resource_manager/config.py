"""The resource manager's configuration: one TOML file per manager process.

Example (``deploy/nodes/examples/manager.toml`` is the annotated full version)::

    [manager]
    id = "mgr1"
    prefix = "pano"
    rate_hz = 10.0
    latency_ms = 200.0
    matcher = "greedy"          # or "global"
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
from typing import Annotated, Any, Literal

import msgspec

from common.area import Area, AreaSpec
from common.clock import ClockSettings
from common.config import ConfigStruct, load_config, resolve_path
from common.errors import ConfigError
from common.keys import DEFAULT_PREFIX, Keys, validate_id
from common.session import SessionSettings
from common.site import XY, SiteConfig, site_sensor_ids, zone_sensor_ids
from resource_manager.track.model import TrackModel

__all__ = [
    "ManagerConfig",
    "ManagerSection",
    "MatchSection",
    "MutualSection",
    "PlannerSection",
    "PoseOverride",
    "PtzSection",
    "default_of",
    "for_site",
    "load_manager_config",
]

MAX_PUBLISH_LAG_S = 60.0
"""The longest ``[manager] publish_lag_s``: tracks held longer are no longer a live system's."""

ROOM_FIELDS = ("x_min", "y_min", "x_max", "y_max")
"""What ``[planner] room`` lists, in order."""

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
    """Most fusion ticks per second: the manager fuses each instant every sensor has reached (the watermark of
    their frames, resource_manager/ingest/schedule.py), at the sensors' pace up to this rate."""
    schedule: Literal["watermark", "fixed"] = "watermark"
    """When to fuse: ``watermark`` (as soon as every sensor in use has a frame at or after the instant, or has
    missed the deadline its measured period, delay and jitter predict) or ``fixed`` (``latency_ms`` behind the
    clock on a ``rate_hz`` timer, whether or not the frames arrived long ago: a steady cadence, and the old
    rule to compare against)."""
    latency_ms: Annotated[float, msgspec.Meta(ge=0.0, le=10_000.0)] = 200.0
    """Watermark: the most a late sensor is waited for past its expected next frame (its newest plus one frame
    period) before the others are fused without it; within it, each sensor is waited for as long as its own
    measured delivery delay and jitter predict. Fixed: the delay behind the clock."""
    max_extrapolation_ms: NonNeg = 100.0
    """Furthest a blob is extrapolated (or held) past its nearest frame (at least 0.6 of the sensor's frame
    period); beyond it the sensor sits out the tick."""
    stale_ms: Pos = 1000.0
    """A sensor whose newest frame is older than this (at least 3 frame periods) before the fusion instant is
    left out."""
    max_gap_ms: Pos = 500.0
    """Two frames further apart than this (at least 2.5 frame periods) are not interpolated between (the nearer
    one is held instead)."""
    buffer_frames: PosInt = 64
    """Most frames kept per sensor (bounded memory)."""
    clock_step_ms: Pos = 1500.0
    """A frame this much older than the newest with a higher seq is a sender clock step: the buffer restarts."""
    matcher: Literal["greedy", "global"] = "greedy"
    """Stereo matcher of Eq. 7 by registry name: ``greedy`` (the paper's, O(N^3/3)) or ``global`` (Hungarian)."""
    publish_tentative: bool = False
    """Also publish tracks still waiting for birth confirmation."""
    publish_lag_s: Annotated[float, msgspec.Meta(ge=0.0, le=MAX_PUBLISH_LAG_S)] = 0.0
    """Publish each instant's tracks this long after it (0: live), once the ids of that window have settled: a
    person's first moments under the id their track was confirmed with (a lost person's, taken back, or a new
    one), and a track that turned out to follow another's person under that one's id. The manager's live state
    (PTZ pointing, view plans) does not wait."""
    state_dir: str = ""
    """Where the track log and id counter persist (relative to the config file); "" = ``state/{id}``."""
    history_s: Pos = 600.0
    """How much track history is kept in memory, reloaded at start and served by ``?history=``."""
    history_hz: Pos = 5.0
    """States per track kept in the history (and its log) per second; the live stream is every tick."""
    history_max_mb: Pos = 64.0
    """Most memory the in-memory history takes (MiB, all tracks; ~575 bytes a state): beyond it the oldest states
    go first, so a crowded site keeps less than ``history_s`` rather than growing (the log on disk keeps all)."""
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
    sensor_bytes_per_s: Annotated[float, msgspec.Meta(ge=1e4, le=1e9)] = 2e6
    """Features bytes one sensor may send per second (a budget holding one second of it): beyond it its frames
    are dropped on arrival, before they are copied or decoded (counted in ``dropped_msgs``), and for a second
    after, so are all its frames larger than 1/30 of it (large for a camera at 30 frames/s); its buffer never
    holds more than one second of it. A camera seeing 30 people at 30 frames/s sends ~0.8 MB/s (the
    demo's ~40 KB/s); a flood of 256-blob frames (~200 KB each, hundreds a second) is cut to this."""
    zone: str = ""
    """The zone this manager leads or stands by for: the managers sharing a zone (each its own ``id``) elect one
    leader through zenoh liveliness (resource_manager/serve/election.py); the others fuse the same sensors' frames,
    publish nothing but their status, and take over with the leader's track ids when its token goes. A manager
    started while the zone has a leader stands by. "": no election, the manager always publishes."""
    zone_polygon: list[XY] = []
    """The zone's floor (a simple polygon, metres; ``--site`` with the site's ``[[zones]]`` sets it): the manager
    publishes only the tracks it owns, those inside it, and near its border those it held until they are
    ``zone_band_m`` past it (resource_manager/serve/zones.py). Empty: every track (one manager for the floor)."""
    zone_band_m: Annotated[float, msgspec.Meta(gt=0.0, le=100.0)] = 1.0
    """Half-width of the overlap band along a zone's border where a track keeps the owner it had (the site's
    ``[site] zone_band_m`` with ``--site``: neighbours must agree on it)."""
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
    """``[match]``: the paper's 3D blob match (Eq. 7), which pairs the blobs of new people across views, and the
    error model's pair choice."""

    threshold: Frac = 0.1
    """tau: two blobs are paired only when Eq. 7's confidence exceeds this (raise: fewer, surer pairs, and
    people far from the cameras are found later)."""
    max_range_m: Pos = 100.0
    """Nobody is paired, or seen, farther than this from a camera."""
    width_sigma: Pos = 0.35
    """Spread of ln(W1/W2) in r_wc (a person's frontal and side widths differ by ~0.6)."""
    width_floor: Frac = 0.0
    """Smallest r_wc: raise it (e.g. 0.3) when the nodes merge occluding people into one wide blob."""
    height_sigma: Pos = 0.12
    """Spread of ln(H1/H2) in r_hc."""
    floor_sigma_m: NonNeg = 0.25
    """Part of r_hc: where a blob's feet are visible, z_cam + D tan(bottom) must be the floor within this (plus
    the bearing error times D); 0 disables. Ghosts of crossing rays stand above or below the floor."""
    use_colour: bool = True
    """False: r_is = 1 (colour is not compared when pairing)."""
    width_rel_sigma: Pos = 0.1
    """Relative width error epsilon of the size-ratio method (Eq. 2) and its crossover with Eq. 1."""
    max_birth_pairs: PosInt = 28
    """Most camera pairs matched per tick to find new people (round robin beyond; bounds the cost with many
    cameras: 8 cameras have 28 pairs)."""
    pair_choice: Literal["error_model", "random"] = "error_model"
    """How the pair that localises (``paper`` mode) and is reported is chosen: by the error model (the paper), or
    at random among the cameras that see the person (a baseline to compare against)."""
    feet_sigma_deg: NonNeg = 0.2
    """1-sigma error of a perspective camera's box bottom (the feet) as an elevation: the feet give the floor
    distance ``z / tan(-elev)``, a second measurement beside the bearing. 0: feet distances are not used."""


class MutualSection(ConfigStruct, frozen=True):
    """``[mutual]``: mutual calibration (Eq. 3) of mobile panoramic cameras."""

    enabled: bool = True
    smoothing_s: Pos = 1.0
    """Time constant of the pose smoothing (raise: steadier but lags a moving robot)."""
    timeout_s: Pos = 2.0
    """A calibrated pose not refreshed for this long becomes unknown again."""
    jump_m: Pos = 1.0
    """A raw pose this far from the smoothed one is refused like an outlier; several in a row that agree restart
    the smoothing there (the robot was moved)."""
    boundary_sigma_deg: NonNeg = 0.0
    """Error of one occluding-boundary bearing; 0 = the observer's bearing sigma."""
    default_height_m: Pos = 1.1
    """Camera height of a mobile sensor whose SensorInfo carries no pose with z_m."""
    settle_s: Pos = 3.0
    """A camera whose own node reports no motion for this long (a static camera: once placed) has its pose fixed
    at the mean over that time; from then on sightings only check it (one that disagrees is refused and counted
    against its sender) and only its node reporting motion releases it. Raising it averages longer before fixing;
    lowering it fixes sooner."""
    max_speed_mps: Pos = 1.0
    """While its node reports motion, a camera's pose moves at most this fast beyond its noise (a robot's top
    speed): sightings that would carry it further are refused."""


class PlannerSection(ConfigStruct, frozen=True):
    """``[planner]``: view planning of mobile cameras (Eqs. 4-6, Fig. 4)."""

    enabled: bool = True
    period_s: Pos = 0.5
    room: list[float] = []
    """``[x_min, y_min, x_max, y_max]`` the goals are clipped to; empty: the bounds of the site's ``[area]``, or
    none."""
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
    """Height of the robots' marking band that must stay in view (minimum baseline: bands above the lower elevation
    limit). The band spans 0.50..0.65 m on the paper's 0.9 m robots: its upper part leaves enough rows for the
    occluding boundaries of Eq. 3."""
    elev_margin_deg: NonNeg = 1.0
    """Margin inside the lens' elevation limits for bands and heads."""
    min_band_px: Pos = 12.0
    """Maximum baseline: the ranged body at least this many pixels wide."""
    keep_m: NonNeg = 0.8
    """Clearance from people on the drive and at the goal."""
    found_m: NonNeg = 0.5
    """Cost of moving: a person counts as found within this (CLEAR-MOT's match distance; with predicted error e,
    with probability 1 - exp(-found_m² / e²)); where nobody else can pair the people a robot helps, it moves only
    when the found person-seconds gained over ``horizon_s`` exceed those lost while it drives and settles
    (resource_manager/plan/checks.py). 0: moves cost nothing."""
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
    default_max_priority: Annotated[int, msgspec.Meta(ge=0, le=1000)] = 0
    """The highest PTZ priority an agent's requests get unless ``max_priority`` names it; a request asking more
    is clipped. Equal for all by default: nobody takes a held camera from anybody."""
    max_priority: dict[str, Annotated[int, msgspec.Meta(ge=0, le=1000)]] = {}
    """Agent id -> its cap (``[ptz.max_priority]`` table, e.g. ``security = 10``): priority comes from the agent's
    identity (the key it asks on, which its certificate alone may use), never from what a request says.
    ``deploy/security/make_configs.py --agents "a1 ops:10"`` writes this table for the manager's config."""


class ManagerConfig(ConfigStruct, frozen=True):
    """The whole manager config file."""

    manager: ManagerSection
    zenoh: SessionSettings = msgspec.field(default_factory=SessionSettings)
    clock: ClockSettings = msgspec.field(default_factory=ClockSettings)
    match: MatchSection = msgspec.field(default_factory=MatchSection)
    tracker: TrackModel = msgspec.field(default_factory=TrackModel)
    """``[tracker]``: the tracker's model of people and cameras (:class:`resource_manager.track.model.TrackModel`,
    where every knob is documented)."""
    mutual: MutualSection = msgspec.field(default_factory=MutualSection)
    planner: PlannerSection = msgspec.field(default_factory=PlannerSection)
    ptz: PtzSection = msgspec.field(default_factory=PtzSection)
    pose: list[PoseOverride] = []
    area: AreaSpec | None = None
    """``[area]``: where people can be and its exits (:mod:`common.area`), a fact of the site: normally the site
    file's (``--site``, which replaces this), given here only for a manager run without one."""

    @property
    def keys(self) -> Keys:
        return Keys(self.manager.prefix)

    @property
    def default_bearing_sigma_rad(self) -> float:
        return math.radians(self.manager.default_bearing_sigma_deg)


def default_of(section: type[msgspec.Struct], name: str) -> Any:
    """The default of a config key, as declared (and documented) here: the stages' own parameter records take
    their defaults from it, so each default exists once.

    Raises:
        KeyError: ``section`` has no key ``name``, or it has no default.
    """
    for f in msgspec.structs.fields(section):
        if f.name == name and f.default is not msgspec.NODEFAULT:
            return f.default
    raise KeyError(f"{section.__name__}.{name} has no default")


def _check_zone_polygon(m: ManagerSection) -> None:
    """A zone's floor needs the zone's name, and must be a simple polygon."""
    if m.zone_polygon:
        if not m.zone:
            raise ConfigError("manager.zone_polygon is set but manager.zone is not: name the zone it is")
        Area.of(AreaSpec(polygon=m.zone_polygon), "manager.zone_polygon")


def validate_manager_config(cfg: ManagerConfig, source: str) -> ManagerConfig:
    """Checks msgspec cannot express; raises ConfigError naming the key."""
    try:
        validate_id(cfg.manager.id, "manager.id")
        if cfg.manager.zone:
            validate_id(cfg.manager.zone, "manager.zone")
        _check_zone_polygon(cfg.manager)
        Keys(cfg.manager.prefix)
        for i, sid in enumerate(cfg.manager.sensors):
            if sid != "*":
                validate_id(sid, f"manager.sensors[{i}]")
        for i, p in enumerate(cfg.pose):
            validate_id(p.id, f"pose[{i}].id")
        for aid in cfg.ptz.max_priority:
            validate_id(aid, f"ptz.max_priority.{aid}")
    except ConfigError as err:
        raise ConfigError(f"{source}: {err}") from err
    room = cfg.planner.room
    if room and (len(room) != len(ROOM_FIELDS) or room[0] >= room[2] or room[1] >= room[3]):
        raise ConfigError(f"{source}: planner.room must be [x_min, y_min, x_max, y_max], got {cfg.planner.room!r}")
    if "*" in cfg.manager.sensors and len(cfg.manager.sensors) > 1:
        raise ConfigError(
            f'{source}: manager.sensors is either ["*"] (any sensor) or a list of ids, got {cfg.manager.sensors!r}'
        )
    if cfg.area is not None:
        Area.of(cfg.area, f"{source}: area")
    ids = [p.id for p in cfg.pose]
    if len(set(ids)) != len(ids):
        raise ConfigError(f"{source}: pose ids must be unique, got {ids!r}")
    if cfg.tracker.p_max_inside < cfg.tracker.p_max:
        raise ConfigError(
            f"{source}: tracker.p_max_inside ({cfg.tracker.p_max_inside}) must be >= tracker.p_max "
            f"({cfg.tracker.p_max})"
        )
    if cfg.tracker.p_delete >= cfg.tracker.p_confirm:
        raise ConfigError(
            f"{source}: tracker.p_delete ({cfg.tracker.p_delete}) must be < tracker.p_confirm ({cfg.tracker.p_confirm})"
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


def for_site(cfg: ManagerConfig, site: SiteConfig) -> ManagerConfig:
    """``cfg`` as the manager of ``site``: it fuses exactly the site's sensor nodes (with ``[manager] zone`` on a
    site with ``[[zones]]``: those whose cameras see into that zone), and knows the site's area.

    Raises:
        ConfigError: the site runs no sensor node (its manager would fuse nothing), the zone is none of the site's
            or none of its cameras runs here, or a process config is unreadable.
    """
    sensors = site_sensor_ids(site)
    if not sensors:
        raise ConfigError(f"{site.path}: the site runs no sensor node, so its manager would fuse nothing")
    manager = cfg.manager
    if cfg.manager.zone and site.zones:  # a manager of one zone fuses the cameras that see into it, owns its floor
        sensors = zone_sensor_ids(site, cfg.manager.zone)
        zone = next(z for z in site.zones if z.name == cfg.manager.zone)
        manager = msgspec.structs.replace(manager, zone_polygon=zone.polygon, zone_band_m=site.site.zone_band_m)
    manager = msgspec.structs.replace(manager, sensors=sensors)
    return msgspec.structs.replace(cfg, manager=manager, area=site.area if site.area is not None else cfg.area)
