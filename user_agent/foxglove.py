"""The 3D scene of a site as Foxglove's well-known messages, built with foxglove-sdk's typed schemas.

``foxglove.SceneUpdate`` (people as bodies with heads, labels, velocity arrows and the rays of the camera
pair that localised them; camera bodies; ground-truth figures) and ``foxglove.FrameTransform`` (world ->
each camera) come from :mod:`foxglove.messages`: Foxglove recognises them by their schema, and each
encodes itself (protobuf) with the schema it carries (``get_schema()``). The recorder writes them into
its MCAP file (:mod:`user_agent.record`), the live bridge logs them on typed channels
(:mod:`user_agent.live`).

Pure: builds messages; the recorder and the bridge write them.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Final, TypeAlias

from foxglove.messages import (
    ArrowPrimitive,
    Color,
    CubePrimitive,
    CylinderPrimitive,
    Duration,
    FrameTransform,
    KeyValuePair,
    LinePrimitive,
    LinePrimitiveLineType,
    Point3,
    Quaternion,
    SceneEntity,
    SceneUpdate,
    SpherePrimitive,
    TextPrimitive,
    Timestamp,
    Vector3,
)
from foxglove.messages import (
    Pose as FgPose,
)

from common.schema import ManagerStatus, Pose, PoseEstimate, SensorInfo, Track, TrackSet
from user_agent.colors import id_color
from user_agent.messages import camera_poses, placed_pose

__all__ = [
    "WORLD_FRAME",
    "CameraPlacements",
    "FoxgloveMessage",
    "cameras_scene",
    "frame_transform",
    "tracks_scene",
    "truth_scene",
]

WORLD_FRAME: Final = "world"

FoxgloveMessage: TypeAlias = SceneUpdate | FrameTransform
"""The Foxglove messages the scene is made of (each has ``get_schema()`` and ``encode()``)."""

DEFAULT_HEIGHT_M = 1.7
"""A person's height drawn when the track's is not known (below :data:`MIN_HEIGHT_M`)."""
MIN_HEIGHT_M = 0.5
"""A height below this is no person's (unknown): :data:`DEFAULT_HEIGHT_M` is drawn instead."""
MIN_SPEED_MPS = 0.05
"""A track slower than this gets no velocity arrow."""
BODY_WIDTH_M = 0.45
"""Diameter of a tracked person's body."""
HEAD_SIZE_M = 0.24
"""Diameter of a tracked person's head."""
NECK_M = 0.25
"""Head top to the body's top (the head and neck)."""
TRUTH_WIDTH_M = 0.5
"""Diameter of a ground-truth figure."""
LENS_SIZE_M = 0.15
"""Edge of the cube drawn at a camera's optical centre."""
LABEL_ABOVE_M = 0.25
"""Labels float this far above what they name (ground truth: further, not to cover the track's)."""
TRUTH_LABEL_ABOVE_M = 0.45
FONT_SIZE = 14.0

_WHITE = Color(r=1.0, g=1.0, b=1.0, a=1.0)
_BODY_WHITE = Color(r=0.95, g=0.95, b=0.95, a=1.0)
_TRUTH_GREY = Color(r=0.6, g=0.6, b=0.6, a=0.35)


def _time(stamp_ns: int) -> Timestamp:
    return Timestamp(sec=stamp_ns // 1_000_000_000, nsec=stamp_ns % 1_000_000_000)


def _yaw_quat(yaw_rad: float) -> Quaternion:
    return Quaternion(x=0.0, y=0.0, z=math.sin(yaw_rad / 2), w=math.cos(yaw_rad / 2))


def _pose(x: float, y: float, z: float, yaw_rad: float = 0.0) -> FgPose:
    return FgPose(position=Vector3(x=x, y=y, z=z), orientation=_yaw_quat(yaw_rad))


def _color(ident: str, alpha: float = 1.0) -> Color:
    r, g, b = id_color(ident)
    return Color(r=r, g=g, b=b, a=alpha)


def _text(x: float, y: float, z: float, text: str) -> TextPrimitive:
    return TextPrimitive(
        pose=_pose(x, y, z), billboard=True, font_size=FONT_SIZE, scale_invariant=True, color=_WHITE, text=text
    )


def _lifetime(lifetime_ns: int) -> Duration:
    return Duration(sec=lifetime_ns // 1_000_000_000, nsec=lifetime_ns % 1_000_000_000)


def tracks_scene(
    ts: TrackSet, camera_xyz: dict[str, tuple[float, float, float]], lifetime_s: float = 0.5
) -> SceneUpdate:
    """A SceneUpdate drawing each tracked person (body, head, label, velocity, rays of its camera pair).

    Args:
        ts: one TrackSet.
        camera_xyz: known optical centres by sensor id (from SensorInfo poses),
            used to draw the rays from the pair that localised each track.
        lifetime_s: how long an entity stays without an update (so lost tracks vanish).
    """
    life = _lifetime(int(lifetime_s * 1e9))
    return SceneUpdate(entities=[_track_entity(tr, ts.stamp_ns, life, camera_xyz) for tr in ts.tracks])


def _track_entity(
    tr: Track, stamp_ns: int, life: Duration, camera_xyz: dict[str, tuple[float, float, float]]
) -> SceneEntity:
    """One tracked person: body, head, label, velocity arrow and rays, faded while the track is tentative."""
    h = tr.height_m if tr.height_m > MIN_HEIGHT_M else DEFAULT_HEIGHT_M
    col = _color(tr.track_id, 0.9 if tr.state == "confirmed" else 0.5)
    head_z = h - HEAD_SIZE_M / 2
    body_h = h - NECK_M
    return SceneEntity(
        timestamp=_time(stamp_ns),
        frame_id=WORLD_FRAME,
        id=f"track/{tr.track_id}",
        lifetime=life,
        metadata=[
            KeyValuePair(key="track_id", value=tr.track_id),
            KeyValuePair(key="state", value=tr.state),
            KeyValuePair(key="method", value=tr.method),
            KeyValuePair(key="sensors", value=",".join(tr.sensors)),
        ],
        cylinders=[
            CylinderPrimitive(
                pose=_pose(tr.x_m, tr.y_m, body_h / 2),
                color=col,
                bottom_scale=1.0,
                size=Vector3(x=BODY_WIDTH_M, y=BODY_WIDTH_M, z=body_h),
                top_scale=0.9,
            )
        ],
        spheres=[
            SpherePrimitive(
                pose=_pose(tr.x_m, tr.y_m, head_z),
                color=col,
                size=Vector3(x=HEAD_SIZE_M, y=HEAD_SIZE_M, z=HEAD_SIZE_M),
            )
        ],
        texts=[_text(tr.x_m, tr.y_m, h + LABEL_ABOVE_M, f"{tr.track_id} {tr.method} ±{tr.predicted_error_m:.2f} m")],
        arrows=_velocity_arrows(tr, col),
        lines=_rays(tr, camera_xyz, h),
    )


def _rays(tr: Track, camera_xyz: dict[str, tuple[float, float, float]], height_m: float) -> list[LinePrimitive]:
    """The rays from each camera that saw the track to just below its head top (none if no camera is placed)."""
    rays: list[Point3] = []
    for sid in tr.sensors:
        if sid in camera_xyz:
            cx, cy, cz = camera_xyz[sid]
            rays += [Point3(x=cx, y=cy, z=cz), Point3(x=tr.x_m, y=tr.y_m, z=height_m - 0.1)]
    if not rays:
        return []
    return [
        LinePrimitive(
            type=LinePrimitiveLineType.LineList,
            pose=_pose(0, 0, 0),
            thickness=2.0,
            scale_invariant=True,
            points=rays,
            color=_color(tr.track_id, 0.5),
        )
    ]


def _velocity_arrows(tr: Track, col: Color) -> list[ArrowPrimitive]:
    """An arrow on the floor along the track's velocity, as long as its speed in m/s (none when nearly still)."""
    speed = math.hypot(tr.vx_mps, tr.vy_mps)
    if speed > MIN_SPEED_MPS:
        return [
            ArrowPrimitive(
                pose=_pose(tr.x_m, tr.y_m, 0.05, math.atan2(tr.vy_mps, tr.vx_mps)),
                shaft_length=speed,
                shaft_diameter=0.04,
                head_length=0.12,
                head_diameter=0.1,
                color=col,
            )
        ]
    return []


def cameras_scene(infos: list[SensorInfo], stamp_ns: int, poses: Mapping[str, Pose] | None = None) -> SceneUpdate:
    """A SceneUpdate drawing every camera whose pose is known (robot body, lens, label).

    Args:
        infos: the sensors' SensorInfo.
        stamp_ns: the scene's time.
        poses: where each camera is (:func:`user_agent.messages.camera_poses`: surveyed, or mobile cameras where
            the manager's mutual calibration places them); default: the surveyed poses of ``infos`` only.
    """
    entities = []
    for info in infos:
        p = poses.get(info.sensor_id) if poses is not None else placed_pose(info)
        if p is None:
            continue
        cyl = []
        if info.body_radius_m > 0:
            d = 2 * info.body_radius_m
            cyl = [
                CylinderPrimitive(
                    pose=_pose(p.x_m, p.y_m, p.z_m * 0.4),
                    size=Vector3(x=d, y=d, z=p.z_m * 0.8),
                    bottom_scale=1.0,
                    top_scale=1.0,
                    color=_BODY_WHITE,
                )
            ]
        lens = CubePrimitive(
            pose=_pose(p.x_m, p.y_m, p.z_m, p.yaw_rad),
            color=_color(info.sensor_id),
            size=Vector3(x=LENS_SIZE_M, y=LENS_SIZE_M, z=LENS_SIZE_M),
        )
        label = _text(p.x_m, p.y_m, p.z_m + 0.3, f"{info.sensor_id} ({info.kind}, {info.pose_source})")
        entities.append(
            SceneEntity(
                timestamp=_time(stamp_ns),
                frame_id=WORLD_FRAME,
                id=f"camera/{info.sensor_id}",
                lifetime=_lifetime(0),
                cylinders=cyl,
                cubes=[lens],
                texts=[label],
            )
        )
    return SceneUpdate(entities=entities)


def frame_transform(sensor_id: str, pose: Pose | None, stamp_ns: int) -> FrameTransform | None:
    """FrameTransform world -> the sensor's frame (None when its pose is unknown)."""
    if pose is None:
        return None
    return FrameTransform(
        timestamp=_time(stamp_ns),
        parent_frame_id=WORLD_FRAME,
        child_frame_id=sensor_id,
        translation=Vector3(x=pose.x_m, y=pose.y_m, z=pose.z_m),
        rotation=_yaw_quat(pose.yaw_rad),
    )


def truth_scene(people: list[tuple[str, float, float, float]], stamp_ns: int, lifetime_s: float) -> SceneUpdate:
    """A SceneUpdate of ground-truth people ``(id, x_m, y_m, height_m)``: translucent grey figures, for comparison."""
    entities = []
    for pid, x, y, h in people:
        hh = h if h > MIN_HEIGHT_M else DEFAULT_HEIGHT_M
        entities.append(
            SceneEntity(
                timestamp=_time(stamp_ns),
                frame_id=WORLD_FRAME,
                id=f"truth/{pid}",
                lifetime=_lifetime(int(lifetime_s * 1e9)),
                cylinders=[
                    CylinderPrimitive(
                        pose=_pose(x, y, hh / 2),
                        size=Vector3(x=TRUTH_WIDTH_M, y=TRUTH_WIDTH_M, z=hh),
                        bottom_scale=1.0,
                        top_scale=1.0,
                        color=_TRUTH_GREY,
                    )
                ],
                texts=[_text(x, y, hh + TRUTH_LABEL_ABOVE_M, f"truth #{pid}")],
            )
        )
    return SceneUpdate(entities=entities)


class CameraPlacements:
    """Where the scene's cameras are, kept from SensorInfo and the managers' status, and the scene messages for it.

    Surveyed cameras come from their SensorInfo; mobile ones from the managers' mutual calibration
    (``ManagerStatus.poses``, :func:`user_agent.messages.camera_poses`). The recorder and the live Foxglove
    bridge feed it what they receive and log what it returns.
    """

    def __init__(self) -> None:
        self._infos: dict[str, SensorInfo] = {}
        self._estimates: dict[str, list[PoseEstimate]] = {}
        self._poses: dict[str, Pose] = {}

    @property
    def camera_xyz(self) -> dict[str, tuple[float, float, float]]:
        """Known optical centres by sensor id (for :func:`tracks_scene`)."""
        return {s: (q.x_m, q.y_m, q.z_m) for s, q in self._poses.items()}

    def update(self, msg: SensorInfo | ManagerStatus, stamp_ns: int) -> tuple[SceneUpdate | None, list[FrameTransform]]:
        """Take a SensorInfo or ManagerStatus; the cameras' SceneUpdate and the FrameTransforms it changes.

        Returns:
            ``(None, [])`` when the message places no camera (a status without mobile poses).
        """
        if isinstance(msg, SensorInfo):
            self._infos[msg.sensor_id] = msg
            moved = [msg.sensor_id]
        else:
            self._estimates[msg.manager_id] = list(msg.poses)
            moved = [e.sensor_id for e in msg.poses if e.source == "mutual"]
        # Always from the latest estimates: a robot whose pose a manager lost is no longer placed (no rays from it).
        self._poses = camera_poses(self._infos, (e for ests in self._estimates.values() for e in ests))
        if not moved:
            return None, []
        tfs = [tf for sid in moved if (tf := frame_transform(sid, self._poses.get(sid), stamp_ns)) is not None]
        return cameras_scene(list(self._infos.values()), stamp_ns, self._poses), tfs
