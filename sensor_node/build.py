"""Wiring, and the node's source registry: from a NodeConfig to a frame source, a processor and the
sensor's description.

Pure of zenoh: the shell (:mod:`sensor_node.node`) publishes what this builds.
Each ``[source] kind`` has one builder in :data:`SOURCES`. Kinds whose builder lives outside the node
register themselves: :func:`register_source`, or an entry point in the ``panostereo.sources`` group named
after the kind, loaded the first time a config asks for it. The simulated camera (``kind = "sim"``) is one:
its builder is :func:`panostereo.sim_camera.build_simulated`, so the node never imports the simulator.
Which pipeline a node runs follows from its source and camera:

=========================  ==========================  ==================================
source                     camera                      processing
=========================  ==========================  ==================================
sim, panoramic camera      the renderer's models       unwarp + image pipeline + sightings
sim, PTZ camera            [pose] + site optics         image pipeline, world azimuths
opencv / folder            ``[camera] panoramic``      unwarp + image pipeline + sightings
opencv / folder            ``[camera] pinhole``        image pipeline, world azimuths
detections                 calibration JSON            boxes -> Features (no image)
=========================  ==========================  ==================================
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from importlib.metadata import entry_points
from typing import Any, Literal, Protocol

import numpy as np

from common.angles import wrap_angle
from common.cameras import AnnularModel, CylindricalCamera, PinholeCamera
from common.errors import ConfigError
from common.frames import Clock, Frame, FrameSource
from common.schema import (
    Features,
    PanoramicModel,
    PinholeModel,
    Pose,
    PoseSource,
    SensorInfo,
    SensorKind,
    ViewPlan,
)
from sensor_node.config import (
    DetectionsSource,
    FolderSource,
    NodeConfig,
    OpenCvSource,
    epoch_from,
    start_file_from_env,
)
from sensor_node.detections import (
    DetectionFrames,
    box_pixels,
    camera_pose,
    features_from_detections,
    load_calibration,
)
from sensor_node.features import PanoramicGeometry, PinholeGeometry
from sensor_node.pipeline import ImagePipeline
from sensor_node.ptz import PtzHead
from sensor_node.sources import FolderFrames, OpenCvFrames
from sensor_node.tracks2d import Tracker2D
from sensor_node.unwarp import Unwarper

__all__ = [
    "BOX_POINT_SIGMA_M",
    "HEAD_POINT_SIGMA_M",
    "SAME_HEIGHT_M",
    "SOURCES",
    "SOURCE_ENTRY_POINTS",
    "DetectionProcessor",
    "ImageProcessor",
    "NodeParts",
    "PlanFollower",
    "Processor",
    "build_node",
    "panoramic_pipeline",
    "register_source",
    "sensor_info",
    "source_builder",
    "source_kind",
]

HEAD_POINT_SIGMA_M = 0.05
"""Spread of a blob's head bearing point around the person's floor position (m): the head stays within a few
centimetres of the body's axis (the paper: the head's bearing is the most accurate part of a blob)."""
BOX_POINT_SIGMA_M = 0.1
"""...and of a detector box's bottom centre: the feet spread in stride, the box jitters."""
SAME_HEIGHT_M = 1e-6
"""A surveyed camera height this close to the rendered camera's is the same height."""


class Processor(Protocol):
    """Turns one captured frame into Features."""

    def process_frame(self, frame: Frame, seq: int) -> tuple[Features, str]:
        """Features of the frame (``processing_ms`` 0) and the motion state ("ok", "warmup", ...)."""
        ...


class PlanFollower(Protocol):
    """A mobile platform that drives to the goals of the manager's view plans (a robot's driver)."""

    def follow(self, plan: ViewPlan) -> None:
        """Take a view plan (any sensor's: the platform keeps its own); must not block."""
        ...


class ImageProcessor:
    """Frames with pixels through :class:`ImagePipeline` (PTZ: follows the head's pose)."""

    def __init__(self, pipeline: ImagePipeline, ptz: PtzHead | None = None) -> None:
        self.pipeline = pipeline
        self.ptz = ptz
        self._ptz_state: tuple[float, float, float] | None = None

    def process_frame(self, frame: Frame, seq: int) -> tuple[Features, str]:
        assert frame.image is not None
        pose = frame.ptz
        if pose is not None and self.ptz is not None:
            state = (pose.pan_rad, pose.tilt_rad, pose.zoom)
            if state != self._ptz_state:
                # The head moved: new rays, and the background must be learnt afresh.
                self.pipeline.set_geometry(PinholeGeometry(self.ptz.camera(pose)))
                self.pipeline.reset()
                self._ptz_state = state
        self.pipeline.seq = seq
        out = self.pipeline.process(frame.image, frame.stamp_ns, frame.index)
        return out.features, out.state


class DetectionProcessor:
    """Frames of a detection file (boxes) to Features."""

    def __init__(self, sensor_id: str, camera: PinholeCamera, gate_rad: float = 0.05) -> None:
        self.sensor_id = sensor_id
        self.camera = camera
        self.tracker = Tracker2D(gate=gate_rad, max_missed=3, period=2 * math.pi)

    def process_frame(self, frame: Frame, seq: int) -> tuple[Features, str]:
        return self.process_frames([frame], first_seq=seq)[0], "ok"

    def process_frames(self, frames: list[Frame], first_seq: int) -> list[Features]:
        """Frames in order (sequence numbers from ``first_seq``) to Features, the lens model run once over all
        their boxes: one frame live, a recorded file at once in dataset time."""
        boxes = [frame.payload or [] for frame in frames]
        everything = [d for dets in boxes for d in dets]
        az = el = np.zeros(0)
        if everything:
            az, el = self.camera.bearing_elevation(box_pixels(everything))
        out = []
        start = 0
        for k, (frame, dets) in enumerate(zip(frames, boxes, strict=True)):
            end = start + 5 * len(dets)
            out.append(
                features_from_detections(
                    dets,
                    self.camera,
                    sensor_id=self.sensor_id,
                    seq=first_seq + k,
                    stamp_ns=frame.stamp_ns,
                    frame_index=frame.index,
                    tracker=self.tracker,
                    rays=(az[start:end], el[start:end]),
                )
            )
            start = end
        return out


@dataclass(slots=True)
class NodeParts:
    """Everything the shell needs besides the session."""

    source: FrameSource
    processor: Processor
    kind: SensorKind
    model: PanoramicModel | PinholeModel
    pose: Pose | None
    fps: float
    ptz: PtzHead | None = None
    """The PTZ head (PTZ nodes): it takes the manager's commands and reports its pose."""
    plans: PlanFollower | None = None
    """What follows the manager's view plans (a mobile platform that drives to their goals), if any."""
    camera_height_m: float = 0.0
    """Height of the optical centre above the floor from the camera model (panoramic; 0: unknown)."""
    exit_at_end: bool = False
    """The process exits once the source has ended (``[source] at_end = "exit"``)."""


def sensor_info(
    cfg: NodeConfig,
    parts: NodeParts,
    *,
    model: PanoramicModel | PinholeModel | None = None,
    seq: int,
    stamp_ns: int,
    clock_offset_ns: int = 0,
    clock_uncertainty_ns: int = 0,
    clock_source: Literal["ntp", "system"] = "system",
) -> SensorInfo:
    """What the node says about its sensor (SensorInfo): kind, camera model, pose and how it is known, accuracy.

    A robot's x, y and yaw come from mutual calibration (the manager ignores them unless ``pose_source`` is
    "surveyed"); its camera height is known from the camera model and is needed for head heights
    (z = z_cam + D tan(top_elev)) and Eq. 7's height consistency, so it is sent as the pose's z. ``model``:
    the camera model now (a PTZ head's, where it points); default the one the node was built with.
    """
    pose_source: PoseSource = "surveyed" if parts.pose is not None else ("mutual" if cfg.node.mobile else "unknown")
    pose = parts.pose
    if pose is None and cfg.node.mobile and parts.camera_height_m > 0.0:
        pose = Pose(x_m=0.0, y_m=0.0, z_m=parts.camera_height_m, yaw_rad=0.0)
    return SensorInfo(
        sensor_id=cfg.node.id,
        seq=seq,
        stamp_ns=stamp_ns,
        kind=parts.kind,
        model=parts.model if model is None else model,
        pose=pose,
        pose_source=pose_source,
        mobile=cfg.node.mobile,
        body_radius_m=cfg.node.body_radius_m,
        fps=float(parts.fps),
        clock_offset_ns=clock_offset_ns,
        clock_uncertainty_ns=clock_uncertainty_ns,
        clock_source=clock_source,
        bearing_sigma_rad=cfg.node.bearing_sigma_rad,
        point_sigma_m=BOX_POINT_SIGMA_M if isinstance(cfg.source, DetectionsSource) else HEAD_POINT_SIGMA_M,
        blobs_merge=not isinstance(cfg.source, DetectionsSource),
        shared_detector=cfg.source.shared_detector if isinstance(cfg.source, DetectionsSource) else "",
    )


def _surveyed_pose(cfg: NodeConfig) -> Pose | None:
    if cfg.pose is None:
        return None
    yaw = wrap_angle(math.radians(cfg.pose.yaw_deg))
    return Pose(x_m=cfg.pose.x_m, y_m=cfg.pose.y_m, z_m=cfg.pose.z_m, yaw_rad=yaw)


def panoramic_pipeline(cfg: NodeConfig, annular: AnnularModel, cyl: CylindricalCamera) -> ImagePipeline:
    """The image pipeline of a panoramic camera: unwarp, the stages, and sightings of the bodies in ``[[body]]``."""
    return ImagePipeline(
        cfg.node.id, PanoramicGeometry(cyl), cfg.pipeline, Unwarper(annular), list(cfg.body), mobile=cfg.node.mobile
    )


def _detections(cfg: NodeConfig, src: DetectionsSource, pose: Pose | None, clock: Clock) -> NodeParts:
    """A detection file: a camera whose person detector ran elsewhere (boxes, no pixels)."""
    camera = load_calibration(cfg.resolve(src.calibration))
    # A recorded site started by a launcher plays from frame 1 once every process is up (its start file).
    start = start_file_from_env() if src.epoch_ns == 0 else None
    frames = DetectionFrames(
        cfg.resolve(src.file),
        src.fps,
        clock,
        epoch_ns=epoch_from(src.epoch_ns, clock()),
        min_confidence=src.min_confidence,
        max_lag_s=src.max_lag_s,
        loop=src.loop,
        start_file=start,
    )
    proc_d = DetectionProcessor(cfg.node.id, camera)
    return NodeParts(frames, proc_d, "pinhole", camera.to_model(), camera_pose(camera), src.fps)


def _camera(cfg: NodeConfig, src: OpenCvSource | FolderSource, pose: Pose | None, clock: Clock) -> NodeParts:
    """A real camera (OpenCV capture or an image folder) with its ``[camera]`` calibration."""
    cam = cfg.camera
    assert cam is not None  # validated in config
    source: FrameSource
    if isinstance(src, OpenCvSource):
        source = OpenCvFrames(
            src.uri,
            clock,
            fps=src.fps,
            loop=src.loop,
            reconnect_min_s=src.reconnect_min_s,
            reconnect_max_s=src.reconnect_max_s,
        )
    else:
        source = FolderFrames(cfg.resolve(src.path), src.glob, src.fps, clock, loop=src.loop)
    fps = src.fps
    at_exit = src.at_end == "exit"
    if cam.model == "pinhole":
        camera = load_calibration(cfg.resolve(cam.calibration))
        pipe = ImagePipeline(cfg.node.id, PinholeGeometry(camera), cfg.pipeline)
        return NodeParts(
            source, ImageProcessor(pipe), "pinhole", camera.to_model(), camera_pose(camera), fps, exit_at_end=at_exit
        )
    (iw, ih), (pw, ph) = cam.image_size, cam.pano_size
    a0, a1, a2 = cam.radial_poly
    annular = AnnularModel(
        iw, ih, cam.center_px[0], cam.center_px[1], a0, a1, a2, pw, ph, math.radians(cam.psi0_deg), cam.direction
    )
    cyl = CylindricalCamera(pw, ph, cam.f_v_px, cam.v0_px, pose.z_m if pose else cam.height_m, cam.direction)
    proc_p = ImageProcessor(panoramic_pipeline(cfg, annular, cyl))
    return NodeParts(
        source, proc_p, "panoramic", cyl.to_model(), pose, fps, camera_height_m=cyl.height_m, exit_at_end=at_exit
    )


SourceBuilder = Callable[[NodeConfig, Any, Pose | None, Clock], NodeParts]
"""Builds a node from its config, its ``[source]`` table, the surveyed pose (if any) and the clock."""

SOURCE_ENTRY_POINTS = "panostereo.sources"
"""The entry-point group where packages name the builders of the source kinds they add (name = kind)."""

SOURCES: dict[str, SourceBuilder] = {
    "detections": _detections,
    "opencv": _camera,
    "folder": _camera,
}
"""The source registry: a ``[source] kind`` -> the builder of its node."""


def register_source(kind: str, builder: SourceBuilder) -> None:
    """Add (or replace) the builder of a ``[source] kind``."""
    SOURCES[kind] = builder


def source_kind(src: object) -> str:
    """The ``kind`` tag of a ``[source]`` table (``"sim"``, ``"opencv"``, ...)."""
    return str(type(src).__struct_config__.tag)  # type: ignore[attr-defined]


def source_builder(kind: str) -> SourceBuilder:
    """The builder of ``kind``: registered, else loaded from its entry point.

    Raises:
        ConfigError: no package provides the kind.
    """
    if kind not in SOURCES:
        for ep in entry_points(group=SOURCE_ENTRY_POINTS, name=kind):
            register_source(kind, ep.load())
    try:
        return SOURCES[kind]
    except KeyError:
        raise ConfigError(
            f"[source] kind {kind!r}: no builder registered (known: {sorted(SOURCES)}; "
            f"a package adds one under the {SOURCE_ENTRY_POINTS!r} entry points)"
        ) from None


def build_node(cfg: NodeConfig, clock: Clock) -> NodeParts:
    """Build the source and processor a config describes.

    Raises:
        ConfigError: inconsistent config (e.g. a PTZ sim camera without a [pose]).
        SourceError: a source that cannot start (missing folder, unreadable detection file).
    """
    return source_builder(source_kind(cfg.source))(cfg, cfg.source, _surveyed_pose(cfg), clock)
