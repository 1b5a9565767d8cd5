"""Foxglove well-known schemas (JSON) and builders for the 3D scene of a recording.

Foxglove recognises a message by its schema *name* (``foxglove.SceneUpdate``,
``foxglove.FrameTransform``) on a JSON channel whose body follows Foxglove's
JSON schema: times are ``{"sec", "nsec"}``, poses are position + quaternion
(notes/zenoh.md §7.1). The schemas below are written from Foxglove's published
message definitions, limited to the primitives this project draws (the others
are declared as arrays so a reader accepts the full message shape).

Pure: builds dicts; the recorder serialises them.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, Final

from common.schema import ManagerStatus, Pose, PoseEstimate, SensorInfo, TrackSet
from user_agent.colors import id_color
from user_agent.messages import camera_poses, placed_pose

__all__ = [
    "FRAME_TRANSFORM_SCHEMA",
    "SCENE_UPDATE_SCHEMA",
    "WORLD_FRAME",
    "CameraPlacements",
    "cameras_scene",
    "frame_transform",
    "tracks_scene",
    "truth_scene",
]

WORLD_FRAME: Final = "world"

_TIME = {
    "type": "object",
    "title": "time",
    "properties": {"sec": {"type": "integer", "minimum": 0}, "nsec": {"type": "integer", "minimum": 0}},
}
_DURATION = {
    "type": "object",
    "title": "duration",
    "properties": {"sec": {"type": "integer"}, "nsec": {"type": "integer", "minimum": 0}},
}
_VEC3 = {
    "type": "object",
    "title": "foxglove.Vector3",
    "properties": {"x": {"type": "number"}, "y": {"type": "number"}, "z": {"type": "number"}},
}
_QUAT = {
    "type": "object",
    "title": "foxglove.Quaternion",
    "properties": {k: {"type": "number"} for k in ("x", "y", "z", "w")},
}
_POSE = {"type": "object", "title": "foxglove.Pose", "properties": {"position": _VEC3, "orientation": _QUAT}}
_COLOR = {"type": "object", "title": "foxglove.Color", "properties": {k: {"type": "number"} for k in "rgba"}}
_POINT3 = {"type": "object", "title": "foxglove.Point3", "properties": {k: {"type": "number"} for k in "xyz"}}


def _prim(title: str, **props: Any) -> dict[str, Any]:
    return {"type": "object", "title": title, "properties": {"pose": _POSE, "color": _COLOR, **props}}


_ENTITY = {
    "type": "object",
    "title": "foxglove.SceneEntity",
    "properties": {
        "timestamp": _TIME,
        "frame_id": {"type": "string"},
        "id": {"type": "string"},
        "lifetime": _DURATION,
        "frame_locked": {"type": "boolean"},
        "metadata": {
            "type": "array",
            "items": {
                "type": "object",
                "title": "foxglove.KeyValuePair",
                "properties": {"key": {"type": "string"}, "value": {"type": "string"}},
            },
        },
        "arrows": {
            "type": "array",
            "items": _prim(
                "foxglove.ArrowPrimitive",
                shaft_length={"type": "number"},
                shaft_diameter={"type": "number"},
                head_length={"type": "number"},
                head_diameter={"type": "number"},
            ),
        },
        "cubes": {"type": "array", "items": _prim("foxglove.CubePrimitive", size=_VEC3)},
        "spheres": {"type": "array", "items": _prim("foxglove.SpherePrimitive", size=_VEC3)},
        "cylinders": {
            "type": "array",
            "items": _prim(
                "foxglove.CylinderPrimitive",
                size=_VEC3,
                bottom_scale={"type": "number"},
                top_scale={"type": "number"},
            ),
        },
        "lines": {
            "type": "array",
            "items": _prim(
                "foxglove.LinePrimitive",
                type={"type": "integer", "description": "0 LINE_STRIP, 1 LINE_LOOP, 2 LINE_LIST"},
                thickness={"type": "number"},
                scale_invariant={"type": "boolean"},
                points={"type": "array", "items": _POINT3},
                colors={"type": "array", "items": _COLOR},
                indices={"type": "array", "items": {"type": "integer", "minimum": 0}},
            ),
        },
        "triangles": {"type": "array", "items": {"type": "object", "title": "foxglove.TriangleListPrimitive"}},
        "texts": {
            "type": "array",
            "items": _prim(
                "foxglove.TextPrimitive",
                billboard={"type": "boolean"},
                font_size={"type": "number"},
                scale_invariant={"type": "boolean"},
                text={"type": "string"},
            ),
        },
        "models": {"type": "array", "items": {"type": "object", "title": "foxglove.ModelPrimitive"}},
    },
}

SCENE_UPDATE_SCHEMA: Final[dict[str, Any]] = {
    "title": "foxglove.SceneUpdate",
    "description": "An update to the entities displayed in a 3D scene",
    "type": "object",
    "properties": {
        "deletions": {
            "type": "array",
            "items": {
                "type": "object",
                "title": "foxglove.SceneEntityDeletion",
                "properties": {
                    "timestamp": _TIME,
                    "type": {"type": "integer", "description": "0 MATCHING_ID, 1 ALL"},
                    "id": {"type": "string"},
                },
            },
        },
        "entities": {"type": "array", "items": _ENTITY},
    },
}

FRAME_TRANSFORM_SCHEMA: Final[dict[str, Any]] = {
    "title": "foxglove.FrameTransform",
    "description": "A transform between two reference frames in 3D space",
    "type": "object",
    "properties": {
        "timestamp": _TIME,
        "parent_frame_id": {"type": "string"},
        "child_frame_id": {"type": "string"},
        "translation": _VEC3,
        "rotation": _QUAT,
    },
}


def _time(stamp_ns: int) -> dict[str, int]:
    return {"sec": stamp_ns // 1_000_000_000, "nsec": stamp_ns % 1_000_000_000}


def _yaw_quat(yaw_rad: float) -> dict[str, float]:
    return {"x": 0.0, "y": 0.0, "z": math.sin(yaw_rad / 2), "w": math.cos(yaw_rad / 2)}


def _pose(x: float, y: float, z: float, yaw_rad: float = 0.0) -> dict[str, Any]:
    return {"position": {"x": x, "y": y, "z": z}, "orientation": _yaw_quat(yaw_rad)}


def _color(ident: str, alpha: float = 1.0) -> dict[str, float]:
    r, g, b = id_color(ident)
    return {"r": r, "g": g, "b": b, "a": alpha}


def _text(x: float, y: float, z: float, text: str) -> dict[str, Any]:
    white = {"r": 1.0, "g": 1.0, "b": 1.0, "a": 1.0}
    return {
        "pose": _pose(x, y, z),
        "billboard": True,
        "font_size": 14.0,
        "scale_invariant": True,
        "color": white,
        "text": text,
    }


def _entity(stamp_ns: int, ident: str, lifetime_ns: int, **prims: list[dict[str, Any]]) -> dict[str, Any]:
    base: dict[str, Any] = {
        "timestamp": _time(stamp_ns),
        "frame_id": WORLD_FRAME,
        "id": ident,
        "lifetime": {"sec": lifetime_ns // 1_000_000_000, "nsec": lifetime_ns % 1_000_000_000},
        "frame_locked": False,
        "metadata": [],
        **{k: [] for k in ("arrows", "cubes", "spheres", "cylinders", "lines", "triangles", "texts", "models")},
    }
    base.update(prims)
    return base


def tracks_scene(ts: TrackSet, camera_xyz: dict[str, tuple[float, float, float]], lifetime_s: float = 0.5) -> dict:
    """A SceneUpdate drawing each tracked person (body, head, label, velocity, rays of its camera pair).

    Args:
        ts: one TrackSet.
        camera_xyz: known optical centres by sensor id (from SensorInfo poses),
            used to draw the rays from the pair that localised each track.
        lifetime_s: how long an entity stays without an update (so lost tracks vanish).
    """
    life_ns = int(lifetime_s * 1e9)
    entities = []
    for tr in ts.tracks:
        h = tr.height_m if tr.height_m > 0.5 else 1.7
        col = _color(tr.track_id, 0.9 if tr.state == "confirmed" else 0.5)
        speed = math.hypot(tr.vx_mps, tr.vy_mps)
        rays = [
            {"x": cx, "y": cy, "z": cz} for sid in tr.sensors if sid in camera_xyz for cx, cy, cz in [camera_xyz[sid]]
        ]
        lines = []
        if rays:
            pts = []
            for p in rays:
                pts += [p, {"x": tr.x_m, "y": tr.y_m, "z": h - 0.1}]
            lines.append(
                {
                    "type": 2,
                    "pose": _pose(0, 0, 0),
                    "thickness": 2.0,
                    "scale_invariant": True,
                    "points": pts,
                    "color": _color(tr.track_id, 0.5),
                    "colors": [],
                    "indices": [],
                }
            )
        entity = _entity(
            ts.stamp_ns,
            f"track/{tr.track_id}",
            life_ns,
            cylinders=[
                {
                    "pose": _pose(tr.x_m, tr.y_m, (h - 0.25) / 2),
                    "size": {"x": 0.45, "y": 0.45, "z": h - 0.25},
                    "bottom_scale": 1.0,
                    "top_scale": 0.9,
                    "color": col,
                }
            ],
            spheres=[
                {"pose": _pose(tr.x_m, tr.y_m, h - 0.12), "size": {"x": 0.24, "y": 0.24, "z": 0.24}, "color": col}
            ],
            texts=[_text(tr.x_m, tr.y_m, h + 0.25, f"{tr.track_id} {tr.method} ±{tr.predicted_error_m:.2f} m")],
            arrows=[
                {
                    "pose": _pose(tr.x_m, tr.y_m, 0.05, math.atan2(tr.vy_mps, tr.vx_mps)),
                    "shaft_length": speed,
                    "shaft_diameter": 0.04,
                    "head_length": 0.12,
                    "head_diameter": 0.1,
                    "color": col,
                }
            ]
            if speed > 0.05
            else [],
            lines=lines,
        )
        entity["metadata"] = [
            {"key": "track_id", "value": tr.track_id},
            {"key": "state", "value": tr.state},
            {"key": "method", "value": tr.method},
            {"key": "sensors", "value": ",".join(tr.sensors)},
        ]
        entities.append(entity)
    return {"deletions": [], "entities": entities}


def cameras_scene(infos: list[SensorInfo], stamp_ns: int, poses: Mapping[str, Pose] | None = None) -> dict:
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
        col = _color(info.sensor_id)
        cyl = []
        if info.body_radius_m > 0:
            r = info.body_radius_m
            white = {"r": 0.95, "g": 0.95, "b": 0.95, "a": 1.0}
            size = {"x": 2 * r, "y": 2 * r, "z": p.z_m * 0.8}
            cyl = [
                {
                    "pose": _pose(p.x_m, p.y_m, p.z_m * 0.4),
                    "size": size,
                    "bottom_scale": 1.0,
                    "top_scale": 1.0,
                    "color": white,
                }
            ]
        entities.append(
            _entity(
                stamp_ns,
                f"camera/{info.sensor_id}",
                0,
                cylinders=cyl,
                cubes=[
                    {
                        "pose": _pose(p.x_m, p.y_m, p.z_m, p.yaw_rad),
                        "size": {"x": 0.15, "y": 0.15, "z": 0.15},
                        "color": col,
                    }
                ],
                texts=[_text(p.x_m, p.y_m, p.z_m + 0.3, f"{info.sensor_id} ({info.kind}, {info.pose_source})")],
            )
        )
    return {"deletions": [], "entities": entities}


def frame_transform(sensor_id: str, pose: Pose | None, stamp_ns: int) -> dict | None:
    """FrameTransform world -> the sensor's frame (None when its pose is unknown)."""
    p = pose
    if p is None:
        return None
    return {
        "timestamp": _time(stamp_ns),
        "parent_frame_id": WORLD_FRAME,
        "child_frame_id": sensor_id,
        "translation": {"x": p.x_m, "y": p.y_m, "z": p.z_m},
        "rotation": _yaw_quat(p.yaw_rad),
    }


def truth_scene(people: list[tuple[str, float, float, float]], stamp_ns: int, lifetime_s: float) -> dict:
    """A SceneUpdate of ground-truth people ``(id, x_m, y_m, height_m)``: translucent grey figures, for comparison."""
    grey = {"r": 0.6, "g": 0.6, "b": 0.6, "a": 0.35}
    entities = []
    for pid, x, y, h in people:
        hh = h if h > 0.5 else 1.7
        entities.append(
            _entity(
                stamp_ns,
                f"truth/{pid}",
                int(lifetime_s * 1e9),
                cylinders=[
                    {
                        "pose": _pose(x, y, hh / 2),
                        "size": {"x": 0.5, "y": 0.5, "z": hh},
                        "bottom_scale": 1.0,
                        "top_scale": 1.0,
                        "color": grey,
                    }
                ],
                texts=[_text(x, y, hh + 0.45, f"truth #{pid}")],
            )
        )
    return {"deletions": [], "entities": entities}


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

    def update(self, msg: SensorInfo | ManagerStatus, stamp_ns: int) -> tuple[dict | None, list[dict]]:
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
