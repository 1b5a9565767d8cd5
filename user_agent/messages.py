"""Which message type travels on which key (from the key table of ``common.keys``)."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any, Final

from common import schema
from common.codec import decode
from common.errors import ConfigError, SchemaError
from common.keys import KeyKind, Keys
from common.schema import Pose, PoseEstimate, SensorInfo

__all__ = ["TYPE_BY_KIND", "camera_poses", "decode_on_key", "placed_pose", "type_for_key"]

TYPE_BY_KIND: Final[dict[KeyKind, type[Any] | None]] = {
    "sensor": None,
    "sensor_info": schema.SensorInfo,
    "sensor_features": schema.Features,
    "sensor_status": schema.NodeStatus,
    "sensor_ptz": schema.PtzCommand,
    "sensor_ptz_state": schema.PtzState,
    "manager": None,
    "manager_pairs": schema.PairChoice,
    "manager_ptz": schema.PtzRequest,
    "manager_status": schema.ManagerStatus,
    "zone_leader": None,
    "zone_standby": None,
    "tracks": schema.TrackSet,
    "track": schema.Track,
    "plan": schema.ViewPlan,
    "agent": None,
}
"""Payload type per key kind (None: a liveliness token, no payload)."""


def type_for_key(keys: Keys, key: str) -> type[Any] | None:
    """The payload type of a concrete key, or None if it is not a documented data key."""
    try:
        return TYPE_BY_KIND[keys.parse(key).kind]
    except ConfigError:
        return None


def decode_on_key(keys: Keys, key: str, data: bytes) -> Any | None:
    """Decode a payload by its key; None if the key is unknown or the payload invalid."""
    t = type_for_key(keys, key)
    if t is None:
        return None
    try:
        return decode(data, t)
    except SchemaError:
        return None


def placed_pose(info: SensorInfo) -> Pose | None:
    """The sensor's position in the world if its SensorInfo really places it (a surveyed pose).

    A mobile camera's SensorInfo may carry a pose for its height only (``pose_source = "mutual"``,
    x = y = 0): its position is the manager's mutual calibration, not in SensorInfo.
    """
    return info.pose if info.pose is not None and info.pose_source == "surveyed" else None


def camera_poses(infos: Mapping[str, SensorInfo], estimates: Iterable[PoseEstimate] = ()) -> dict[str, Pose]:
    """Where each camera is, as far as anyone knows: surveyed poses from SensorInfo, mobile ones from the manager.

    A camera whose SensorInfo places it (surveyed) keeps that pose. A mobile camera is placed where a manager's
    mutual calibration puts it (``ManagerStatus.poses``), at the optical-centre height its SensorInfo gives (the
    estimate's own height when there is no SensorInfo). Cameras nobody has placed are absent: never guessed.

    Args:
        infos: latest SensorInfo per sensor id.
        estimates: the managers' pose estimates (later ones win).
    """
    out = {sid: p for sid, info in infos.items() if (p := placed_pose(info)) is not None}
    surveyed = set(out)
    for est in estimates:
        if est.sensor_id in surveyed:
            continue
        info = infos.get(est.sensor_id)
        z_m = info.pose.z_m if info is not None and info.pose is not None else est.pose.z_m
        out[est.sensor_id] = Pose(x_m=est.pose.x_m, y_m=est.pose.y_m, z_m=z_m, yaw_rad=est.pose.yaw_rad)
    return out
