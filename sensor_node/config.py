"""The sensor node's TOML config: one file per camera process.

Layout (every table but ``[node]`` and ``[source]`` is optional)::

    [node]
    id = "pano1"                 # sensor id: [a-z0-9][a-z0-9-]*
    prefix = "pano"              # key prefix of the site
    mobile = false               # camera on a robot (pose from mutual calibration)
    body_radius_m = 0.18         # radius of this robot's white cylinder (0: none)
    bearing_sigma_rad = 0.0035   # 1-sigma head-bearing error published in SensorInfo

    [zenoh]                      # common.session.SessionSettings
    connect = ["tcp/127.0.0.1:7447"]

    [clock]                      # common.clock.ClockSettings
    ntp_server = ""

    [source]
    kind = "sim"                 # sim | opencv | folder | detections (keys per kind below)

    [camera]                     # real cameras only (sim: the renderer's own models)
    model = "panoramic"          # panoramic | pinhole

    [pose]                       # optional surveyed pose of the optical centre
    x_m = 2.0
    y_m = 1.5
    z_m = 1.1
    yaw_deg = 0.0

    [[body]]                     # other robots this node may see (mutual calibration, Eq. 3)
    id = "pano2"
    band_rgb = [40, 90, 220]
    radius_m = 0.18

    [pipeline]                   # knobs of the image pipeline (see PipelineSettings)

Relative paths (site, calibration, detection file, image folder) are resolved
against the config file's folder by :func:`load_node_config`.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Annotated, Literal

import msgspec

from common.clock import ClockSettings
from common.config import ConfigStruct, load_config, resolve_path
from common.errors import ConfigError
from common.keys import DEFAULT_PREFIX, Keys, validate_id
from common.schema import MAX_HIST_BINS, OptId
from common.session import SessionSettings

__all__ = [
    "EPOCH_ENV",
    "START_ENV",
    "BodySpec",
    "CameraSettings",
    "DetectionsSource",
    "FolderSource",
    "NodeConfig",
    "NodeSection",
    "OpenCvSource",
    "PipelineSettings",
    "PoseSettings",
    "SimSource",
    "SourceSettings",
    "epoch_from",
    "load_node_config",
    "read_start_file",
    "source_kind",
    "start_file_from_env",
]

EPOCH_ENV = "PANOSTEREO_EPOCH_NS"
"""Environment variable with the site's common world epoch (Unix ns), set by the launcher."""
START_ENV = "PANOSTEREO_START_FILE"
"""Environment variable naming a file the launcher writes once every process of a site is up: recorded sources
(detection files) wait for it and play their frame 1 at the Unix ns it holds (the world epoch)."""
BAND_BOUNDS = 2
"""``band_z_m`` is [bottom_m, top_m], or empty for the default band."""

Pos = Annotated[float, msgspec.Meta(gt=0.0)]
NonNeg = Annotated[float, msgspec.Meta(ge=0.0)]
Frac = Annotated[float, msgspec.Meta(ge=0.0, le=1.0)]
PosInt = Annotated[int, msgspec.Meta(ge=1)]
RGB = Annotated[list[Annotated[int, msgspec.Meta(ge=0, le=255)]], msgspec.Meta(min_length=3, max_length=3)]
Size2 = Annotated[list[Annotated[int, msgspec.Meta(ge=8, le=100_000)]], msgspec.Meta(min_length=2, max_length=2)]


class NodeSection(ConfigStruct, frozen=True):
    """``[node]``: who this sensor is."""

    id: str
    prefix: str = DEFAULT_PREFIX
    mobile: bool = False
    """True for a camera on a robot: its pose comes from mutual calibration, not ``[pose]``."""
    body_radius_m: NonNeg = 0.0
    """Radius of this platform's cylindrical body, from the floor up to the camera, that other robots see and
    that hides people behind it from the other cameras (0: no body)."""
    bearing_sigma_rad: Annotated[float, msgspec.Meta(ge=0.0, le=1.0)] = 0.0035
    """1-sigma head-bearing error this sensor expects; the manager's error model uses it."""


class SimSource(ConfigStruct, frozen=True, tag_field="kind", tag="sim"):
    """``kind = "sim"``: render a camera of a simulated site (its pixels are all the pipeline sees)."""

    site: str
    """The site with the world and the camera's true placement: a bundled site by name (``"demo"``), or a site
    file (a path relative to this config)."""
    camera: str = ""
    """Camera id in the site file (default: ``node.id``)."""
    epoch_ns: Annotated[int, msgspec.Meta(ge=0)] = 0
    """World time 0 as Unix ns; 0 takes env PANOSTEREO_EPOCH_NS, else the node's start time."""
    fps: NonNeg = 0.0
    """Frames per second (0: the site's fps)."""
    seed: int = -1
    """Sensor-noise seed (-1: derived from the site seed and the camera id)."""


class OpenCvSource(ConfigStruct, frozen=True, tag_field="kind", tag="opencv"):
    """``kind = "opencv"``: a capture device, video file or network stream via ``cv2.VideoCapture``."""

    uri: str
    """Device index ("0"), file path, or rtsp:// / http:// URL."""
    fps: NonNeg = 0.0
    """Pace file playback at this rate (0: the file's own rate; live sources are never paced)."""
    loop: bool = False
    """Files: start again at the end instead of ending."""
    at_end: Literal["stay", "exit"] = "stay"
    """Files, when they end (not looping): "stay" up, the status saying "ended", until stopped; "exit"
    the process (exit code 0) once the last frame's Features are out."""
    reconnect_min_s: Pos = 0.5
    """First wait before reopening a failed source; doubles up to ``reconnect_max_s``."""
    reconnect_max_s: Pos = 10.0


class FolderSource(ConfigStruct, frozen=True, tag_field="kind", tag="folder"):
    """``kind = "folder"``: images in a folder, in name order, at a fixed rate."""

    path: str
    glob: str = "*.png"
    fps: Pos = 10.0
    loop: bool = False
    at_end: Literal["stay", "exit"] = "stay"
    """When the last image is read (not looping): "stay" up, or "exit" the process (exit code 0)."""


class DetectionsSource(ConfigStruct, frozen=True, tag_field="kind", tag="detections"):
    """``kind = "detections"``: a MOTChallenge det file + pinhole calibration (no images)."""

    file: str
    """``frame,id,left,top,width,height,conf,...`` per line, 1-based frames."""
    calibration: str
    """JSON ``{"model": "pinhole", "image_size": [w, h], "K", "dist", "R", "t"}`` or ``{"P": 3x4}``."""
    fps: Pos = 2.0
    """Frame k is world time (k - 1) / fps."""
    epoch_ns: Annotated[int, msgspec.Meta(ge=0)] = 0
    """World time 0 as Unix ns; 0 takes env PANOSTEREO_EPOCH_NS, else the node's start time."""
    min_confidence: NonNeg = 0.0
    """Detections with a lower ``conf`` column are ignored."""
    shared_detector: OptId = ""
    """Name of the multi-view detector whose floor detections these boxes are, drawn into this camera's picture (the
    same name in every camera's file: its views find or miss a person together, covered or not); "": the boxes are
    this camera's own detector's, on its own picture. A fact of how the file was made."""
    max_lag_s: Pos = 1.0
    """Frames due longer ago than this (node started late) are skipped and counted as dropped."""
    loop: bool = False


SourceSettings = SimSource | OpenCvSource | FolderSource | DetectionsSource


class CameraSettings(ConfigStruct, frozen=True):
    """``[camera]``: the calibrated model of a real camera (sim cameras use the renderer's models)."""

    model: Literal["panoramic", "pinhole"] = "panoramic"
    # -- panoramic (annular PAL image -> cylinder, paper Steps 1-3)
    image_size: Size2 = msgspec.field(default_factory=lambda: [768, 576])
    center_px: Annotated[list[float], msgspec.Meta(min_length=2, max_length=2)] = msgspec.field(
        default_factory=lambda: [383.5, 287.5]
    )
    """Ring centre (x, y) in the annular image (Step 1)."""
    radial_poly: Annotated[list[float], msgspec.Meta(min_length=3, max_length=3)] = msgspec.field(
        default_factory=lambda: [100.0, 1.0, 0.0]
    )
    """a0, a1, a2 of r = a0 + a1 v + a2 v^2 (Step 2)."""
    psi0_deg: float = 0.0
    direction: Literal[-1, 1] = 1
    pano_size: Size2 = msgspec.field(default_factory=lambda: [1080, 162])
    f_v_px: Pos = 256.0
    v0_px: float = 93.0
    height_m: Pos = 1.1
    """Height of the virtual viewpoint above the floor (Step 3)."""
    # -- pinhole
    calibration: str = ""
    """Pinhole: calibration JSON (see DetectionsSource.calibration); bearings are then world azimuths."""


class PoseSettings(ConfigStruct, frozen=True):
    """``[pose]``: surveyed pose of the optical centre in the world."""

    x_m: float
    y_m: float
    z_m: float
    yaw_deg: float = 0.0


class BodySpec(ConfigStruct, frozen=True):
    """``[[body]]``: another robot's cylinder body, identified by its band colour."""

    id: str
    band_rgb: RGB
    radius_m: Pos = 0.18
    height_m: Pos = 0.9
    """Height of the top of the body above the floor (blobs below it are the robot, not a person)."""
    band_z_m: Annotated[list[NonNeg], msgspec.Meta(max_length=2)] = []
    """Heights [bottom, top] of the marking band above the floor ([]: 0.55..0.72 of ``height_m``, the
    demo robots' design). A sighting whose Eq. 3 range disagrees with the range the band's elevation
    gives is not that body (a shirt of the band's colour, a band cut by the image edge)."""

    @property
    def band_range_m(self) -> tuple[float, float]:
        """(bottom, top) of the band above the floor."""
        if len(self.band_z_m) == BAND_BOUNDS:
            return float(self.band_z_m[0]), float(self.band_z_m[1])
        return 0.55 * self.height_m, 0.72 * self.height_m


class PipelineSettings(ConfigStruct, frozen=True):
    """``[pipeline]``: image-pipeline knobs. Each says what raising or lowering it does."""

    fg_threshold: Annotated[int, msgspec.Meta(ge=1, le=255)] = 16
    """Least grey-level difference from the background that counts as changed. Lower: fainter people found,
    more noise specks; higher: fewer false pixels, low-contrast clothing breaks up."""
    fg_sigmas: Annotated[float, msgspec.Meta(ge=0.0)] = 4.0
    """A pixel is changed when it departs from the background by more than this many sigmas of its own
    swing (what moves in place: a flapping tape, leaves) or of the image's noise, and by at least
    ``fg_threshold``. Both are measured by the model (the warm-up's spread, then outside people), so
    a noisy or compressed camera needs no retuning. Higher: fewer false pixels, faint people break up."""
    shadows: bool = True
    """Changed pixels that are the background dimmed or brightened with its hue kept (cast shadows,
    highlights) are not objects (:mod:`sensor_node.background.shadows`). Off: grey levels only."""
    diff_threshold: Annotated[int, msgspec.Meta(ge=1, le=255)] = 22
    """Grey-level frame-to-frame difference that counts as motion (frame differencing)."""
    learning_rate: Frac = 0.05
    """Weight of the current frame in the background average (outside objects). Higher: follows slow
    light drift faster but absorbs people who stand still sooner; lower: the opposite."""
    update_every: PosInt = 4
    """Update the background every N frames (the rate is scaled to match). Higher: cheaper, slower."""
    abnormal_frac: Frac = 0.35
    """Fraction of changed pixels that means a sudden global change (light switch, camera moved) rather
    than people. Lower: re-initialises more eagerly; higher: big crowds are not mistaken for it."""
    ego_motion_frac: Frac = 0.5
    """Fraction of the image's column sectors (36) with frame-to-frame motion that means the camera itself
    moves (a robot driving): nothing is reported and the background is learnt afresh once it stops.
    Lower: detects slow driving sooner, a crowd close around the camera may pass for it; 1: off."""
    warmup_frames: PosInt = 12
    """Frames whose median initialises the background, spread over ``warmup_s``; nothing is reported
    meanwhile. Higher: cleaner start with people present, more work at start."""
    warmup_s: Pos = 1.5
    """Seconds (of frame stamps) the warm-up samples span: the blind start. Higher: people who stand
    still for a while at start leave no ghost; longer blind start."""
    warmup_stride: Annotated[int, msgspec.Meta(ge=0)] = 0
    """Take every N-th frame for the warm-up instead (0: spread over ``warmup_s`` by the stamps)."""
    ghost_frames: PosInt = 10
    """Frames a changed region must stay still before it is tested for being a ghost (something that
    left the background; a start-up hole is tested at its first still sample, by the surface beside it).
    Lower: ghosts vanish sooner, more tests; higher: the opposite."""
    group_scale: PosInt = 2
    """Reduction of the mask that connected components and grouping run on (1: full resolution).
    Higher: cheaper; thin or tiny regions may be missed. Boxes and heads stay full resolution."""
    still_absorb_frames: PosInt = 45
    """Frames after which a changed region that has not moved becomes background unless its outline is
    an edge of the current frame and not of the background (a paused person: kept however long). Higher:
    ambiguous still regions stay longer; lower: ghosts on textured floors vanish sooner."""
    still_keep_frames: PosInt = 150
    """Frames a still region whose outline is in the frame (a paused person) is kept out of the
    background at most (counted up to ~1000; 150 = 10 s at 15 fps, twice the demo's longest pause).
    Higher: people who stand for long stay detected; lower: a ghost revealing a contrasted background
    (it passes the person test) and a robot that parked in view (no band visible) vanish sooner."""
    min_component_px: PosInt = 6
    """Connected regions smaller than this are noise and ignored before grouping."""
    merge_gap_px: Annotated[list[int], msgspec.Meta(min_length=2, max_length=2)] = msgspec.field(
        default_factory=lambda: [4, 8]
    )
    """(columns, rows): regions closer than this merge into one blob. Higher: split bodies rejoin, but
    neighbouring people merge; lower: the opposite."""
    min_blob_px: PosInt = 60
    """Blobs with fewer changed pixels are dropped. Lower: small/far people kept, more false blobs."""
    min_changed_frac: Frac = 0.25
    """A blob is kept only if this fraction of its bounding box changed (paper: enough pixels changed)."""
    min_blob_height_px: PosInt = 10
    min_blob_width_px: PosInt = 5
    """Narrower blobs are dropped (a person 10 m away is ~7 px wide in a 1080 px panorama)."""
    split_dip_px: Annotated[int, msgspec.Meta(ge=0)] = 8
    """A blob whose top profile has two peaks (heads) with a valley this many rows below the lower one
    is split there into two objects, each side having to rise to a head (0: never); ghosts that were
    merged into people become blobs of their own. Lower: people side by side separate sooner, a
    shoulder may pass for a head; higher: merged people stay merged."""
    split_gap_cols: Annotated[int, msgspec.Meta(ge=0)] = 1
    """A blob whose vertical projection profile has a gap (columns with at most one changed pixel) at
    least this many columns wide is parted there (grouping joins regions up to ``merge_gap_px`` apart:
    people walking side by side), if each side passes the blob checks and rises to a head narrower than
    its body, or is wide, or reaches the image's top row; a narrow flat strip (an arm swung clear of
    the body) stays with its neighbour. 0: never."""
    track_split_hits: Annotated[int, msgspec.Meta(ge=0)] = 5
    """A blob that holds the predicted head columns of two or more 2D tracks, each seen standing alone in
    at least this many frames, is cut between them, at a shallow valley or where the far head comes out
    from behind the near one (:mod:`sensor_node.segmentation.groups`): people in a tight group stay apart when they
    were apart a moment ago. 0: off. Lower: groups part sooner, an arm split off for a few frames may
    keep cutting its own body; higher: the opposite."""
    head_edges: bool = True
    """Place each head row's ends to sub-pixel precision from the partly covered edge pixels (their
    difference to the background) instead of the thresholded mask's whole pixels. Off: the mask only."""
    head_ratio: Pos = 1.5
    """Head box height:width (paper: 3:2). Only the head's bearing is used, so it is not critical."""
    hist_bins: Annotated[list[int], msgspec.Meta(min_length=2, max_length=2)] = msgspec.field(
        default_factory=lambda: [16, 4]
    )
    """Hue x saturation bins of the photometric feature I (product <= 512). More: finer, noisier."""
    track_gate_px: Pos = 40.0
    """Largest head move (px) between frames for a 2D track to continue. Higher: fewer id switches on
    fast motion, more swaps between neighbours."""
    track_max_missed: Annotated[int, msgspec.Meta(ge=0)] = 15
    """Frames a 2D track survives without a blob before its local id is retired (15: a person hidden for
    up to a second keeps their id). Higher: fewer new ids after occlusions, more wrong re-use."""
    sighting_every: PosInt = 2
    """Look for other robots' bodies every N frames (their last sightings are repeated in between)."""
    band_min_px: PosInt = 12
    """Pixels of a body's band colour needed to accept a sighting. Lower: farther robots, more false hits."""
    band_tolerance: Annotated[float, msgspec.Meta(gt=0.0, le=1.0)] = 0.12
    """Largest chromaticity distance from a body's band colour (0..1). Higher: tolerant to light colour,
    more confusion with clothing."""


class NodeConfig(ConfigStruct, frozen=True):
    """A whole sensor-node config file."""

    node: NodeSection
    source: SourceSettings
    zenoh: SessionSettings = msgspec.field(default_factory=SessionSettings)
    clock: ClockSettings = msgspec.field(default_factory=ClockSettings)
    camera: CameraSettings | None = None
    pose: PoseSettings | None = None
    body: list[BodySpec] = []
    pipeline: PipelineSettings = msgspec.field(default_factory=PipelineSettings)
    path: str = ""
    """Where the file was read from (set by :func:`load_node_config`, not written in the file)."""

    @property
    def keys(self) -> Keys:
        return Keys(self.node.prefix)

    def resolve(self, value: str) -> Path:
        """A path written in this config, resolved against the file's folder."""
        return resolve_path(self.path or "node.toml", value)


def source_kind(source: SourceSettings) -> str:
    """The ``kind`` tag of a ``[source]`` table."""
    return str(type(source).__struct_config__.tag)


def start_file_from_env() -> Path | None:
    """The start file of ``PANOSTEREO_START_FILE``, if the launcher set one."""
    env = os.environ.get(START_ENV, "").strip()
    return Path(env) if env else None


def read_start_file(path: Path) -> int | None:
    """The epoch (Unix ns) a start file holds, or None while it is not written yet.

    Raises:
        ConfigError: a start file that is not one non-negative integer.
    """
    try:
        text = path.read_text(encoding="utf-8").strip()
    except FileNotFoundError:
        return None
    except OSError as err:
        raise ConfigError(f"start file {str(path)!r}: {err.strerror}") from err
    try:
        epoch = int(text)
    except ValueError as err:
        raise ConfigError(f"start file {str(path)!r}: expected integer Unix ns, got {text[:40]!r}") from err
    if epoch < 0:
        raise ConfigError(f"start file {str(path)!r}: expected >= 0, got {epoch}")
    return epoch


def epoch_from(value_ns: int, fallback_ns: int) -> int:
    """The world epoch: the config value, else env ``PANOSTEREO_EPOCH_NS``, else ``fallback_ns``.

    Raises:
        ConfigError: if the environment variable is not a non-negative integer.
    """
    if value_ns > 0:
        return value_ns
    env = os.environ.get(EPOCH_ENV, "").strip()
    if env:
        try:
            epoch = int(env)
        except ValueError as err:
            raise ConfigError(f"environment {EPOCH_ENV}: expected integer Unix ns, got {env!r}") from err
        if epoch < 0:
            raise ConfigError(f"environment {EPOCH_ENV}: expected >= 0, got {epoch}")
        return epoch
    return fallback_ns


def validate(cfg: NodeConfig) -> NodeConfig:
    """Cross-field checks the schema cannot express.

    Raises:
        ConfigError: naming the file, the key, what was expected and what was given.
    """
    src = cfg.path or "node config"
    validate_id(cfg.node.id, f"{src}: node.id")
    Keys(cfg.node.prefix)  # validates the prefix
    seen: set[str] = set()
    for i, body in enumerate(cfg.body):
        validate_id(body.id, f"{src}: body[{i}].id")
        if body.id in seen:
            raise ConfigError(f"{src}: body[{i}].id {body.id!r} appears twice")
        seen.add(body.id)
        if body.band_z_m and not (len(body.band_z_m) == BAND_BOUNDS and body.band_z_m[0] < body.band_z_m[1]):
            raise ConfigError(
                f"{src}: body[{i}].band_z_m: expected [bottom_m, top_m] with bottom < top, got {body.band_z_m}"
            )
    bins = cfg.pipeline.hist_bins
    if bins[0] < 1 or bins[1] < 1 or bins[0] * bins[1] > MAX_HIST_BINS:
        raise ConfigError(f"{src}: pipeline.hist_bins: expected two positive counts with product <= 512, got {bins}")
    gap = cfg.pipeline.merge_gap_px
    if gap[0] < 0 or gap[1] < 0:
        raise ConfigError(f"{src}: pipeline.merge_gap_px: expected [cols >= 0, rows >= 0], got {gap}")
    if isinstance(cfg.source, OpenCvSource | FolderSource):
        if cfg.camera is None:
            raise ConfigError(
                f"{src}: source.kind = {source_kind(cfg.source)!r} needs a [camera] table (the calibrated model)"
            )
        if cfg.camera.model == "pinhole" and not cfg.camera.calibration:
            raise ConfigError(f"{src}: camera.calibration: expected a calibration JSON path for model 'pinhole'")
    calibrated = isinstance(cfg.source, DetectionsSource) or (
        isinstance(cfg.source, OpenCvSource | FolderSource) and cfg.camera is not None and cfg.camera.model == "pinhole"
    )
    if calibrated and cfg.pose is not None:
        # The calibration's R and t place a pinhole camera (its bearings are world azimuths); a [pose]
        # beside it would be a second, silently ignored answer.
        raise ConfigError(
            f"{src}: [pose]: a calibrated pinhole camera takes its pose from its calibration (R, t); "
            "expected no [pose] table, got one (remove it, or convert a calibration that places the camera: "
            "`panostereo calib convert`)"
        )
    if isinstance(cfg.source, OpenCvSource) and cfg.source.reconnect_max_s < cfg.source.reconnect_min_s:
        raise ConfigError(
            f"{src}: source.reconnect_max_s: expected >= reconnect_min_s ({cfg.source.reconnect_min_s}), "
            f"got {cfg.source.reconnect_max_s}"
        )
    return cfg


def load_node_config(path: str | Path) -> NodeConfig:
    """Read and validate a sensor-node config file.

    Raises:
        ConfigError: file missing, bad TOML, unknown/missing key, bad value; naming file and key.
    """
    cfg = load_config(path, NodeConfig)
    cfg = msgspec.structs.replace(cfg, path=str(Path(path)))
    return validate(cfg)
