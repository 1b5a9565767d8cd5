"""What the refinement measures: every camera's foot and head rays of the people it saw, in its own frame.

A blob (or detector box) of a person standing on the floor gives two rays from the camera's centre: through the
feet (the box's bottom centre, on the floor) and through the top of the head. Rays are kept in the camera's own
frame (:mod:`.poses`), so they do not change when the camera's pose does; only where they point in the world does.

* pinhole cameras (``SensorInfo.kind == "pinhole"``: detection files, calibrated perspective cameras): the rays
  through the box's bottom-centre and top-centre pixels, by the camera's own model (K, distortion);
* level cameras (panoramic, PTZ heads): the blob's bearing with its bottom and top elevations (the node's
  own camera model made them), turned into the sensor frame by the pose the node published.

Sources: a dataset site's detection files, turned into Features by the sensor node's own code
(:func:`panostereo.datasets.play.load_cameras`), or a recording (``agent record``) of a live site, whose
Features and SensorInfo every sensor published. Frames of different cameras are put on common *instants*: a
dataset's frame numbers, or for a live recording a grid at the slowest camera's frame period, each camera
contributing its frame nearest to each grid instant (within half a period).
"""

from __future__ import annotations

import logging
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from common.arrays import BoolArray, FloatArray, IntArray
from common.errors import ConfigError
from common.pinhole import PinholeCamera
from common.schema import Features, PinholeModel, SensorInfo
from common.site import SiteConfig, site_sensor_ids
from panostereo.calib.poses import CameraPose

__all__ = ["CameraRays", "from_features", "from_recording", "from_site"]

logger = logging.getLogger(__name__)

DEFAULT_POINT_SIGMA_M = 0.1
"""Spread of a ray's point around the person's axis (m) when the sensor does not state it (``point_sigma_m``)."""
HEAD_TRUSTED_CONFIDENCE = 0.5
"""A level camera's blob below this confidence may have its head above the picture: its head ray is not used."""


@dataclass(frozen=True, slots=True, eq=False)
class CameraRays:
    """One camera's observations: rays of people, one row per blob, in the camera's own frame."""

    sensor_id: str
    info: SensorInfo
    """What the sensor said about itself (model, pose) when the rays were measured."""
    pose: CameraPose
    """The calibration the rays were measured with: the refinement's starting guess."""
    point_sigma_m: float
    instant: IntArray
    """(n,) index of the common instant of each blob."""
    track: IntArray
    """(n,) the node's 2D track id (the same person across this camera's frames)."""
    foot: FloatArray
    """(n, 3) unit rays through the feet, own frame."""
    head: FloatArray
    """(n, 3) unit rays through the top of the head, own frame."""
    feet_ok: BoolArray
    """(n,) the feet are in the picture (the foot ray is a floor point)."""
    head_ok: BoolArray
    """(n,) the top of the head is in the picture."""
    head_plane: FloatArray | None = None
    """(n, 3) pinhole cameras: unit normal (own frame) of the plane through the centre and the box's top row. A
    box's top edge is the highest point of the person, which lies on the image of the vertical through the
    feet, not at the top edge's centre when the camera is rolled: the head is only known to be on this plane."""

    @property
    def n(self) -> int:
        return int(self.instant.size)


def _unit(v: FloatArray) -> FloatArray:
    return np.asarray(v / np.linalg.norm(v, axis=1, keepdims=True), dtype=np.float64)


def _level_ray(bearing_rad: FloatArray, elev_rad: FloatArray) -> FloatArray:
    ce = np.cos(elev_rad)
    return np.column_stack([ce * np.cos(bearing_rad), ce * np.sin(bearing_rad), np.sin(elev_rad)])


def camera_pose(info: SensorInfo) -> CameraPose | None:
    """The pose a sensor's rays were measured with (None: it has none, or moves: a robot's mutual calibration)."""
    if info.kind == "pinhole" and isinstance(info.model, PinholeModel):
        cam = PinholeCamera.from_model(info.model)
        return CameraPose(np.array(cam.r), cam.center_world, level=False)
    if info.pose is None or info.pose_source != "surveyed" or info.mobile:
        return None
    p = info.pose
    return CameraPose.from_yaw(p.x_m, p.y_m, p.z_m, p.yaw_rad)


def from_features(info: SensorInfo, frames: Iterable[tuple[int, Features]]) -> CameraRays | None:
    """One camera's rays from its Features, each with the index of its common instant.

    Returns None for a camera the refinement cannot place (no surveyed pose, a robot, no known model).
    """
    pose = camera_pose(info)
    if pose is None:
        return None
    inst: list[int] = []
    track: list[int] = []
    rows: list[tuple[float, ...]] = []
    for k, f in frames:
        if f.state != "ok":
            continue
        for b in f.blobs:
            inst.append(k)
            track.append(b.local_id)
            rows.append(
                (
                    b.bearing_rad,
                    b.top_elev_rad,
                    b.bottom_elev_rad,
                    b.bbox_u_px,
                    b.bbox_v_px,
                    b.bbox_w_px,
                    b.bbox_h_px,
                    float(b.feet_visible),
                    b.confidence,
                )
            )
    a = np.array(rows, dtype=np.float64).reshape(-1, 9)
    head_plane = None
    if pose.level:
        foot = _level_ray(a[:, 0], a[:, 2])
        head = _level_ray(a[:, 0], a[:, 1])
        head_ok = a[:, 8] >= HEAD_TRUSTED_CONFIDENCE
    else:
        assert isinstance(info.model, PinholeModel)
        cam = PinholeCamera.from_model(info.model)
        cx = a[:, 3] + a[:, 5] / 2.0
        foot = _unit(cam.ray_world(np.column_stack([cx, a[:, 4] + a[:, 6]])) @ cam.r.T)
        head = _unit(cam.ray_world(np.column_stack([cx, a[:, 4]])) @ cam.r.T)
        along = _unit(cam.ray_world(np.column_stack([cx + 1.0, a[:, 4]])) @ cam.r.T)
        head_plane = _unit(np.cross(head, along))
        head_ok = a[:, 4] > 0.0
    return CameraRays(
        sensor_id=info.sensor_id,
        info=info,
        pose=pose,
        point_sigma_m=info.point_sigma_m or DEFAULT_POINT_SIGMA_M,
        instant=np.array(inst, dtype=np.int64),
        track=np.array(track, dtype=np.int64),
        foot=foot,
        head=head,
        feet_ok=a[:, 7] != 0.0,
        head_ok=head_ok,
        head_plane=head_plane,
    )


def _spread(indices: Sequence[int], limit: int) -> set[int]:
    """At most ``limit`` of ``indices``, evenly spread (all when ``limit`` is 0)."""
    if not limit or len(indices) <= limit:
        return set(indices)
    picks = np.linspace(0, len(indices) - 1, limit).round().astype(int)
    return {indices[i] for i in picks}


def from_site(site: SiteConfig, frames: int = 0) -> tuple[list[CameraRays], list[str]]:
    """Every camera of a dataset site (detection files), its frames the instants; at most ``frames`` of them.

    Returns:
        (cameras with rays, notes on cameras left out).

    Raises:
        ConfigError: not a dataset site of detection-file nodes.
    """
    from panostereo.datasets.play import load_cameras

    cams = load_cameras(site)
    n = max((len(c.features) for c in cams), default=0)
    keep = _spread(list(range(n)), frames)
    out: list[CameraRays] = []
    notes: list[str] = []
    for c in cams:
        rays = from_features(c.info, ((k, f) for k, f in enumerate(c.features) if k in keep))
        if rays is None:
            notes.append(f"{c.sensor_id}: no calibration to refine")
        else:
            out.append(rays)
    return out, notes


def from_recording(path: str | Path, site: SiteConfig, frames: int = 0) -> tuple[list[CameraRays], list[str]]:
    """Every static camera of ``site`` in a recording of it, on common instants; at most ``frames`` of them.

    Raises:
        ConfigError: not a readable recording, or it holds no Features of the site's cameras.
    """
    from user_agent.messages import decode_on_key
    from user_agent.record import keys_for
    from user_agent.recording import iter_raw

    wanted = set(site_sensor_ids(site))
    infos: dict[str, SensorInfo] = {}
    feats: dict[str, list[Features]] = {}
    for s in iter_raw(path):
        keys = keys_for(s.key)
        if keys is None or keys.prefix != site.site.prefix:
            continue
        msg = decode_on_key(keys, s.key, s.data)
        if isinstance(msg, SensorInfo) and msg.sensor_id in wanted:
            infos[msg.sensor_id] = msg
        elif isinstance(msg, Features) and msg.sensor_id in wanted:
            feats.setdefault(msg.sensor_id, []).append(msg)
    if not feats:
        raise ConfigError(
            f"{path}: holds no Features of the site's cameras ({', '.join(sorted(wanted)) or 'none'}): "
            "record the live site with `panostereo agent record` while people walk"
        )
    notes = [f"{sid}: not in the recording" for sid in sorted(wanted - set(feats))]
    notes += [f"{sid}: the recording has no SensorInfo of it" for sid in sorted(set(feats) - set(infos))]
    periods = []
    for fs in feats.values():
        stamps = np.array(sorted(f.stamp_ns for f in fs), dtype=np.float64)
        if stamps.size > 1:
            periods.append(float(np.median(np.diff(stamps))))
    period_ns = max(periods) if periods else 1e9
    t0 = min(f.stamp_ns for fs in feats.values() for f in fs)
    t1 = max(f.stamp_ns for fs in feats.values() for f in fs)
    n = round((t1 - t0) / period_ns) + 1
    keep = _spread(list(range(n)), frames)
    out: list[CameraRays] = []
    for sid in sorted(set(feats) & set(infos)):
        best: dict[int, tuple[float, Features]] = {}
        for f in feats[sid]:
            k = round((f.stamp_ns - t0) / period_ns)
            off = abs(f.stamp_ns - t0 - k * period_ns)
            if k in keep and off <= period_ns / 2 and (k not in best or off < best[k][0]):
                best[k] = (off, f)
        rays = from_features(infos[sid], ((k, best[k][1]) for k in sorted(best)))
        if rays is None:
            notes.append(f"{sid}: its pose is not surveyed (a robot: mutual calibration places it): left as it is")
        else:
            out.append(rays)
    return out, notes
