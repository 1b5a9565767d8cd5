"""Every message that crosses a process boundary, declared once.

Wire format: MessagePack maps (field name -> value) of frozen msgspec Structs,
each carrying an explicit ``type`` tag (``"pano.<Name>"``) so a plain
``msgpack`` client sees a dict with the documented field names.

Rules that hold for every message:

* every message names its sender (``sensor_id``, ``manager_id`` or
  ``agent_id``), and carries ``seq`` (per-sender, per-key counter) and
  ``stamp_ns`` (Unix epoch ns on the sender's NTP-corrected clock; for
  Features, the capture time of the frame);
* units are in field names (``_ns``, ``_rad``, ``_m``, ``_px``, ``_mps``);
* every float is bounded (hence finite), every angle is in range, every list
  and string has a maximum length, so a hostile payload cannot make a
  receiver allocate without bound;
* schemas evolve only by appending fields with defaults; a breaking change is
  a new version namespace in ``common.keys``.

Frames used below:

* *sensor frame*: a level frame at the camera's optical centre. A bearing is
  an azimuth, counter-clockwise from the sensor's x axis; an elevation is the
  angle above the horizontal plane through the centre. For a panoramic camera
  the x axis is the panorama's column 0 (rotated by ``yaw_rad`` in the world);
  for a pinhole/PTZ camera whose pose is known, the node reports bearings
  directly as world azimuths and its pose has ``yaw_rad = 0``.
* *world frame*: the floor plane, z up, metres. ``world_bearing = yaw_rad +
  bearing_rad``.
"""

from __future__ import annotations

import math
from typing import Annotated, Final, Literal

import msgspec

__all__ = [
    "MESSAGE_TYPES",
    "Blob",
    "DetectorState",
    "Features",
    "Latency",
    "ManagerStatus",
    "NodeStatus",
    "PairChoice",
    "PairEntry",
    "PanoramicModel",
    "PinholeModel",
    "Pose",
    "PoseEstimate",
    "PtzCommand",
    "PtzReply",
    "PtzRequest",
    "PtzState",
    "Refusal",
    "SensorAgreement",
    "SensorInfo",
    "SensorTiming",
    "Sighting",
    "Track",
    "TrackSet",
    "ViewPlan",
]

# ---------------------------------------------------------------------------
# Bounded scalar types
# ---------------------------------------------------------------------------

MAX_BLOBS: Final = 256
"""Most blobs one Features message may carry."""
MAX_SIGHTINGS: Final = 32
MAX_HIST_BINS: Final = 512
MAX_TRACKS: Final = 256
MAX_SENSORS: Final = 64
MAX_ID_LEN: Final = 48
MAX_TEXT_LEN: Final = 256

ID_PATTERN: Final = r"^[a-z0-9][a-z0-9-]*$"

Id = Annotated[str, msgspec.Meta(min_length=1, max_length=MAX_ID_LEN, pattern=ID_PATTERN)]
"""A sensor, manager, agent or track id: ``[a-z0-9][a-z0-9-]*``."""
OptId = Annotated[str, msgspec.Meta(max_length=MAX_ID_LEN, pattern=r"^([a-z0-9][a-z0-9-]*)?$")]
"""An id, or the empty string for "none"."""
Text = Annotated[str, msgspec.Meta(max_length=MAX_TEXT_LEN)]
Seq = Annotated[int, msgspec.Meta(ge=0, le=2**63 - 1)]
StampNs = Annotated[int, msgspec.Meta(ge=0, le=2**63 - 1)]
"""Unix epoch nanoseconds."""
DurationNs = Annotated[int, msgspec.Meta(ge=-(2**62), le=2**62)]
Count = Annotated[int, msgspec.Meta(ge=0, le=2**63 - 1)]

MAX_METRES: Final = 1e5
"""The largest distance or coordinate a message carries (m): 100 km."""
Metres = Annotated[float, msgspec.Meta(ge=-MAX_METRES, le=MAX_METRES)]
"""A coordinate in metres (finite, within 100 km)."""
PosMetres = Annotated[float, msgspec.Meta(ge=0.0, le=MAX_METRES)]
Speed = Annotated[float, msgspec.Meta(ge=-1e3, le=1e3)]
Bearing = Annotated[float, msgspec.Meta(ge=-math.pi, le=math.pi)]
"""An azimuth in radians, wrapped to [-pi, pi]."""
Elevation = Annotated[float, msgspec.Meta(ge=-math.pi / 2, le=math.pi / 2)]
AngleSpan = Annotated[float, msgspec.Meta(ge=0.0, le=2 * math.pi)]
"""A non-negative angular extent in radians."""
Pixels = Annotated[float, msgspec.Meta(ge=-1e5, le=1e5)]
PosPixels = Annotated[float, msgspec.Meta(ge=0.0, le=1e5)]
Unit = Annotated[float, msgspec.Meta(ge=0.0, le=1.0)]
"""A value in [0, 1] (probability, confidence, normalised bin)."""
Millis = Annotated[float, msgspec.Meta(ge=0.0, le=1e9)]
Rate = Annotated[float, msgspec.Meta(ge=0.0, le=1e6)]
Zoom = Annotated[float, msgspec.Meta(ge=0.1, le=1000.0)]
Variance = Annotated[float, msgspec.Meta(ge=0.0, le=1e10)]
Covariance = Annotated[float, msgspec.Meta(ge=-1e10, le=1e10)]
Coef = Annotated[float, msgspec.Meta(ge=-1e9, le=1e9)]
Priority = Annotated[int, msgspec.Meta(ge=0, le=1000)]

Hist = Annotated[list[Unit], msgspec.Meta(max_length=MAX_HIST_BINS)]
IdList = Annotated[list[Id], msgspec.Meta(max_length=MAX_SENSORS)]


class _Msg(msgspec.Struct, frozen=True, kw_only=True, tag_field="type", forbid_unknown_fields=False):
    """Base of every wire struct: frozen, keyword-only, tagged."""


# ---------------------------------------------------------------------------
# Sensor node -> manager
# ---------------------------------------------------------------------------


class Blob(_Msg, frozen=True, tag="pano.Blob"):
    """One moving-object blob of one frame: the paper's T_i = (I, theta, w, h)."""

    local_id: Count
    """Node-local 2D track id: the same person keeps it across frames of one sensor."""
    bearing_rad: Bearing
    """theta: azimuth of the head centre in the sensor frame."""
    width_rad: AngleSpan
    """w: angular width of the blob (body) in radians."""
    top_elev_rad: Elevation
    """h: elevation of the top of the blob (top of the head)."""
    bottom_elev_rad: Elevation
    """Elevation of the bottom of the blob (feet, when visible)."""
    bbox_u_px: Pixels
    """Bounding box left column in the processed image (pixels)."""
    bbox_v_px: Pixels
    """Bounding box top row (pixels)."""
    bbox_w_px: PosPixels
    bbox_h_px: PosPixels
    hist: Hist = []
    """I: L1-normalised colour histogram of the blob pixels (empty: no colour)."""
    changed_frac: Unit = 1.0
    """Fraction of the blob's pixels that changed against the background."""
    feet_visible: bool = True
    """False when the blob touches the image border or is cut by occlusion."""
    confidence: Unit = 1.0
    """How far the bearing and top can be trusted: 1.0, or lower (panoramic nodes: 0.3) when the blob reaches
    the image's top row, so the head may be above the view (a person within ~1.5-2 m): the bearing may be the
    neck's or shoulders' and ``top_elev_rad`` is the image's top edge, a lower bound. Detection-file nodes: the
    detector's score."""


class Sighting(_Msg, frozen=True, tag="pano.Sighting"):
    """Another robot's cylindrical body seen in this panorama (Eq. 3)."""

    target_id: OptId
    """Sensor id of the sighted robot, from its body marking; "" if unidentified."""
    left_rad: Bearing
    """Bearing of one occluding boundary (sensor frame)."""
    right_rad: Bearing
    """Bearing of the other occluding boundary."""
    alpha_rad: AngleSpan
    """Angle between the two occluding rays."""
    bearing_rad: Bearing
    """Bearing of the cylinder axis: mean of the two boundaries."""
    distance_m: PosMetres
    """Baseline B = R / sin(alpha / 2) with the target's body radius R."""
    body_radius_m: PosMetres


DetectorState = Literal["ok", "learning", "moving"]


class Features(_Msg, frozen=True, tag="pano.Features"):
    """Everything one frame of one camera yields; published per frame."""

    sensor_id: Id
    seq: Seq
    stamp_ns: StampNs
    """Capture time of the frame on the node's NTP-corrected clock."""
    frame_index: Count
    blobs: Annotated[list[Blob], msgspec.Meta(max_length=MAX_BLOBS)] = []
    sightings: Annotated[list[Sighting], msgspec.Meta(max_length=MAX_SIGHTINGS)] = []
    processing_ms: Millis = 0.0
    """Time from capture to publication of this message."""
    state: DetectorState = "ok"
    """Whether an empty ``blobs`` list means nobody is there: "ok" (the detector sees), "learning" (the
    background model is being (re)learnt, e.g. just after start or after the camera moved: no blobs yet,
    whoever is there), "moving" (the camera itself moves: no blobs until it stops)."""


class Pose(_Msg, frozen=True, tag="pano.Pose"):
    """Where a sensor's optical centre is, in the world frame."""

    x_m: Metres
    y_m: Metres
    z_m: Metres
    """Height of the optical centre above the floor."""
    yaw_rad: Bearing
    """Rotation of the sensor frame's x axis from the world x axis."""


class PanoramicModel(_Msg, frozen=True, tag="pano.PanoramicModel"):
    """The 4-parameter cylindrical virtual camera (paper, Step 3)."""

    width_px: Annotated[int, msgspec.Meta(ge=8, le=100_000)]
    """Panorama width: f_h = width_px / (2 pi)."""
    height_px: Annotated[int, msgspec.Meta(ge=8, le=100_000)]
    f_v_px: Annotated[float, msgspec.Meta(gt=0.0, le=1e6)]
    """Vertical focal length in pixels."""
    v0_px: Pixels
    """Row of the horizon circle."""
    direction: Annotated[int, msgspec.Meta(ge=-1, le=1)] = 1
    """+1: bearing grows with the column; -1: it decreases."""


class PinholeModel(_Msg, frozen=True, tag="pano.PinholeModel"):
    """A perspective camera: K, distortion and pose, x_cam = R x_world + t."""

    width_px: Annotated[int, msgspec.Meta(ge=8, le=100_000)]
    height_px: Annotated[int, msgspec.Meta(ge=8, le=100_000)]
    k: Annotated[list[Coef], msgspec.Meta(min_length=9, max_length=9)]
    """Row-major 3x3 intrinsics."""
    dist: Annotated[list[Coef], msgspec.Meta(max_length=14)] = []
    r: Annotated[list[Coef], msgspec.Meta(min_length=9, max_length=9)] = msgspec.field(
        default_factory=lambda: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
    )
    """Row-major world-to-camera rotation."""
    t_m: Annotated[list[Coef], msgspec.Meta(min_length=3, max_length=3)] = msgspec.field(
        default_factory=lambda: [0.0, 0.0, 0.0]
    )


PoseSource = Literal["surveyed", "mutual", "unknown"]
SensorKind = Literal["panoramic", "ptz", "pinhole"]


class SensorInfo(_Msg, frozen=True, tag="pano.SensorInfo"):
    """What a sensor is and where (as far as it knows); queryable and put on change."""

    sensor_id: Id
    seq: Seq
    stamp_ns: StampNs
    kind: SensorKind
    model: PanoramicModel | PinholeModel
    pose: Pose | None = None
    """Surveyed pose from the node's configuration; None when not known."""
    pose_source: PoseSource = "unknown"
    mobile: bool = False
    """True for a camera on a robot: its pose comes from mutual calibration."""
    body_radius_m: PosMetres = 0.0
    """Radius of the cylinder body others see (0: none): from the floor up to the camera, it hides what stands
    behind it from the other cameras."""
    fps: Rate = 0.0
    clock_offset_ns: DurationNs = 0
    clock_uncertainty_ns: Count = 0
    clock_source: Literal["ntp", "system"] = "system"
    bearing_sigma_rad: Annotated[float, msgspec.Meta(ge=0.0, le=1.0)] = 0.0035
    """1-sigma head-bearing error this sensor expects (feeds the error model)."""
    point_sigma_m: Annotated[float, msgspec.Meta(ge=0.0, le=10.0)] = 0.0
    """Spread (1 sigma, m) of the point this sensor measures around the person's floor position: a head sways
    little, a box's bottom centre moves with the legs. 0: not stated (the manager assumes its default)."""
    blobs_merge: bool = False
    """True when this sensor's blobs are foreground segments (the paper's background subtraction): people who overlap
    in its picture may come as one blob, whose bottom is then the nearer one's feet. False: one box per person (a
    person detector's)."""
    shared_detector: OptId = ""
    """The multi-view detector this sensor's boxes come from, by name, when they are not its own: one detection per
    person on the floor, drawn into every view whose picture holds them (a multi-view detector's output, or an
    annotation made on the floor). The sensors that name the same detector find or miss a person together, and find
    them whether or not nearer people cover them. "": this camera's own detector, on its own picture."""


SourceState = Literal["starting", "ok", "reconnecting", "failed", "ended"]


class NodeStatus(_Msg, frozen=True, tag="pano.NodeStatus"):
    """A sensor node's health, published at 1 Hz."""

    sensor_id: Id
    seq: Seq
    stamp_ns: StampNs
    fps: Rate
    frames: Count
    dropped_frames: Count
    processing_ms: Millis
    """Mean pipeline time per frame over the last interval."""
    clock_offset_ns: DurationNs
    clock_uncertainty_ns: Count
    clock_source: Literal["ntp", "system"]
    decode_errors: Count
    source_state: SourceState
    message: Text = ""
    """Human-readable detail, e.g. why the source failed."""
    dropped_msgs: Count = 0
    """Incoming messages (PTZ commands, plans) lost to a full buffer."""


class PtzCommand(_Msg, frozen=True, tag="pano.PtzCommand"):
    """Point a PTZ camera (manager -> node)."""

    manager_id: Id
    seq: Seq
    stamp_ns: StampNs
    sensor_id: Id
    pan_rad: Bearing
    """World azimuth of the optical axis."""
    tilt_rad: Elevation
    zoom: Zoom = 1.0
    track_id: OptId = ""


class PtzState(_Msg, frozen=True, tag="pano.PtzState"):
    """Where a PTZ head points now (node -> all)."""

    sensor_id: Id
    seq: Seq
    stamp_ns: StampNs
    pan_rad: Bearing
    tilt_rad: Elevation
    zoom: Zoom
    moving: bool = False


# ---------------------------------------------------------------------------
# Manager -> agents
# ---------------------------------------------------------------------------

Method = Literal["triangulation", "size_ratio", "least_squares", "predicted"]
TrackState = Literal["tentative", "confirmed", "coasting"]


class Track(_Msg, frozen=True, tag="pano.Track"):
    """One person's state on the floor at the fusion instant."""

    manager_id: Id
    seq: Seq
    stamp_ns: StampNs
    """The fusion instant this state refers to."""
    track_id: Id
    """Unique across managers: ``{manager_id}-{n}``."""
    x_m: Metres
    y_m: Metres
    height_m: PosMetres
    """Height of the top of the head above the floor (0: unknown)."""
    vx_mps: Speed
    vy_mps: Speed
    cov_xx_m2: Variance
    cov_xy_m2: Covariance
    cov_yy_m2: Variance
    state: TrackState
    method: Method
    """How the latest measurement was made ("predicted": no measurement this tick)."""
    sensors: IdList = []
    """The cameras whose views localised it this tick (the chosen pair)."""
    predicted_error_m: PosMetres = 0.0
    """The error model's predicted distance error of that pair."""
    age_s: Annotated[float, msgspec.Meta(ge=0.0, le=1e9)] = 0.0
    hits: Count = 0
    misses: Count = 0


class TrackSet(_Msg, frozen=True, tag="pano.TrackSet"):
    """All current tracks of one manager at one fusion instant."""

    manager_id: Id
    seq: Seq
    stamp_ns: StampNs
    tracks: Annotated[list[Track], msgspec.Meta(max_length=MAX_TRACKS)] = []
    sensors_used: IdList = []
    published_ns: StampNs = 0
    """When the manager published it, on its NTP-corrected clock: ``published_ns - stamp_ns`` is the capture ->
    publish age (0: not published live, e.g. a dataset evaluation)."""


class PairEntry(_Msg, frozen=True, tag="pano.PairEntry"):
    """The camera pair chosen for one track, and why."""

    track_id: Id
    sensor_a: Id
    sensor_b: Id
    predicted_error_m: PosMetres
    method: Method
    candidates: Count = 0
    """How many camera pairs could see the person."""


class PairChoice(_Msg, frozen=True, tag="pano.PairChoice"):
    """Per tick: which camera pair localised which track, with predicted error."""

    manager_id: Id
    seq: Seq
    stamp_ns: StampNs
    choices: Annotated[list[PairEntry], msgspec.Meta(max_length=MAX_TRACKS)] = []


class ViewPlan(_Msg, frozen=True, tag="pano.ViewPlan"):
    """Where a mobile camera should go to see its assigned person best (Fig. 4)."""

    manager_id: Id
    seq: Seq
    stamp_ns: StampNs
    sensor_id: Id
    """The mobile camera that should move."""
    partner_id: Id
    """The main camera O1 of the virtual stereo pair."""
    track_id: Id
    goal_x_m: Metres
    goal_y_m: Metres
    baseline_m: PosMetres
    phi1_rad: AngleSpan
    predicted_error_m: PosMetres
    """Predicted distance error at the goal, for the sensor's bearing error."""
    current_error_m: PosMetres
    """Predicted distance error from where the camera is now."""


class PoseEstimate(_Msg, frozen=True, tag="pano.PoseEstimate"):
    """Where the manager believes one sensor is, and how it knows."""

    sensor_id: Id
    pose: Pose
    source: PoseSource
    """``surveyed`` (configuration) or ``mutual`` (mutual calibration, Eq. 3)."""
    sigma_m: PosMetres = 0.0
    """1-sigma position uncertainty (0 for surveyed poses)."""


class Refusal(_Msg, frozen=True, tag="pano.Refusal"):
    """Messages a manager refused from one sender id (the id in their key), by reason."""

    sender_id: Id
    """The sensor (or agent) id the refused messages' keys named."""
    unlisted: Count = 0
    """Not a sensor this manager fuses: refused by key, before decoding."""
    wrong_id: Count = 0
    """The payload named another sender than its key."""
    skewed: Count = 0
    """Features stamped more than the manager's ``max_skew_s`` behind its clock (late frames; never buffered)."""
    ahead: Count = 0
    """Features stamped more than the manager's ``max_lead_s`` ahead of its clock (a sender's clock is off; never
    buffered)."""
    sighting: Count = 0
    """Instants at which its sightings of another camera disagreed with the other witnesses or with that camera's
    settled pose: refused (no single witness moves a camera)."""


class SensorTiming(_Msg, frozen=True, tag="pano.SensorTiming"):
    """How one sensor's frames reach the manager, as its fusion schedule measures them."""

    sensor_id: Id
    period_ms: Millis
    """Its measured frame period."""
    delay_ms: Annotated[float, msgspec.Meta(ge=-1e9, le=1e9)]
    """Capture -> arrival at the manager (node processing plus transport), running mean."""
    jitter_ms: Millis
    """The delay's and the period's running mean absolute deviation."""
    wait_ms: Millis
    """How long past its expected next frame the manager waits for it before fusing the others without it."""
    frames: Count = 0
    """Frames received from it so far."""
    late_frames: Count = 0
    """Frames that arrived after their instant was fused (dropped from it), so far."""
    missed: Count = 0
    """Deadlines it missed (the others were fused without it), so far."""


class SensorAgreement(_Msg, frozen=True, tag="pano.SensorAgreement"):
    """Whether one camera's blobs agree with where the other cameras put the people (a bumped camera does not)."""

    sensor_id: Id
    residual_m: PosMetres
    """Median floor distance from its blobs' rays to the nearest person the others localised, over the window (a
    blob that finds nobody within the manager's gate counts as the gate)."""
    blobs: Count
    """Blobs behind that median."""
    unexplained_frac: Unit = 0.0
    """Share of its blobs in the window that found nobody within the gate."""
    disagrees: bool = False
    """True when the residual is too large for a camera in place, or has grown well past the camera's own in place
    (it was moved while the manager ran): re-calibrate it (``panostereo calib refine``)."""
    settled_m: PosMetres | None = None
    """The camera's own residual in place, learned over its first checks (None until then, and for a camera that
    disagreed from the start)."""


class Latency(_Msg, frozen=True, tag="pano.Latency"):
    """Where the time from capture to a published TrackSet went, medians over the status period."""

    age_ms: Millis
    """Capture -> publish age of the newest TrackSet."""
    age_p50_ms: Millis
    age_p99_ms: Millis
    node_ms: Millis
    """The node's processing of the frame each instant waited for last (capture -> publish)."""
    transport_ms: Millis
    """That frame's node -> manager transport."""
    wait_ms: Millis
    """Its arrival -> the fusion starting (the watermark, or the fixed delay)."""
    fusion_ms: Millis
    """The fusion tick."""
    publish_ms: Millis
    """The fusion's end -> the TrackSet handed to zenoh."""


class ManagerStatus(_Msg, frozen=True, tag="pano.ManagerStatus"):
    """The resource manager's health, published at 1 Hz."""

    manager_id: Id
    seq: Seq
    stamp_ns: StampNs
    tick_ms: Millis
    """Mean fusion tick time over the last interval (wall clock: what the tracks wait for)."""
    tick_p99_ms: Millis
    tick_rate_hz: Rate
    sensors_in_use: IdList = []
    sensors_known: IdList = []
    sensors_without_pose: IdList = []
    tracks: Count = 0
    decode_errors: Count = 0
    late_msgs: Count = 0
    duplicate_msgs: Count = 0
    out_of_order_msgs: Count = 0
    dropped_msgs: Count = 0
    sensors_absent: IdList = []
    """Known sensors whose liveliness token is gone."""
    poses: Annotated[list[PoseEstimate], msgspec.Meta(max_length=MAX_SENSORS)] = []
    """The pose of every sensor the manager currently knows where it is."""
    sensors_expected: IdList = []
    """The sensors this manager fuses (its site's, or ``[manager] sensors``); empty when it accepts any."""
    refused_msgs: Count = 0
    """Every message refused so far (unlisted sender, payload id unlike its key, stamp off the clock)."""
    refused: Annotated[list[Refusal], msgspec.Meta(max_length=MAX_SENSORS)] = []
    """Refused messages per sender id, the most refused first."""
    refused_partial: bool = False
    """True when unlisted senders flooded faster than the manager counts them: their counts are lower bounds."""
    schedule: Literal["watermark", "fixed"] = "watermark"
    """When it fuses (``[manager] schedule``)."""
    frames_received: Count = 0
    """Features messages that reached the fusion so far, every sensor's."""
    latency: Latency | None = None
    """Capture -> publish of its TrackSets over the status period (None: nothing published in it)."""
    timing: Annotated[list[SensorTiming], msgspec.Meta(max_length=MAX_SENSORS)] = []
    """Per sensor in use: its frames' measured period, delay and jitter, and how late they came."""
    agreement: Annotated[list[SensorAgreement], msgspec.Meta(max_length=MAX_SENSORS)] = []
    """Per camera: how well its blobs agree with the other cameras' people, the worst first
    (:mod:`resource_manager.poses.agreement`)."""
    zone: OptId = ""
    """The zone whose leadership it shares (``[manager] zone``; "": none, it always publishes)."""
    role: Literal["leader", "standby"] = "leader"
    """``standby``: it fuses, silent, ready to take over from its zone's leader."""
    leader_id: OptId = ""
    """The manager leading its zone as this one sees it ("": none, or no zone)."""
    tick_cpu_ms: Millis = 0.0
    """Mean CPU time of the fusing thread per tick over the interval: the fusion's own work, without the time it
    waited for a core (``tick_ms`` includes that wait on a busy host)."""


# ---------------------------------------------------------------------------
# Agent <-> manager: PTZ allocation (query on manager/{id}/ptz)
# ---------------------------------------------------------------------------


class PtzRequest(_Msg, frozen=True, tag="pano.PtzRequest"):
    """An agent asks for (or releases) a PTZ view of a track."""

    agent_id: Id
    seq: Seq
    stamp_ns: StampNs
    action: Literal["acquire", "release"]
    track_id: Id
    priority: Priority = 0
    """Higher wins when several agents want the same camera."""
    lease_s: Annotated[float, msgspec.Meta(ge=0.0, le=86_400.0)] = 0.0
    """How long the hold lasts unless renewed (an ``acquire`` again); 0: the manager's ``[ptz] lease_s``."""


class PtzReply(_Msg, frozen=True, tag="pano.PtzReply"):
    """The manager's answer: which camera, or why none."""

    manager_id: Id
    seq: Seq
    stamp_ns: StampNs
    ok: bool
    track_id: Id
    sensor_id: OptId = ""
    reason: Text = ""
    lease_s: Annotated[float, msgspec.Meta(ge=0.0, le=86_400.0)] = 0.0
    """An acquired hold ends this long after the request unless renewed, or when the agent's liveliness
    token goes; 0 when nothing is held."""


MESSAGE_TYPES: Final[tuple[type[_Msg], ...]] = (
    Features,
    SensorInfo,
    NodeStatus,
    PtzCommand,
    PtzState,
    Track,
    TrackSet,
    PairChoice,
    ViewPlan,
    ManagerStatus,
    PtzRequest,
    PtzReply,
)
"""Top-level messages (the ones that travel alone on a key)."""
