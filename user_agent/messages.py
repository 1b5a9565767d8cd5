"""Which message type travels on which key (from the key table of ``common.keys``)."""

from __future__ import annotations

from typing import Any, Final

from common import schema
from common.codec import decode
from common.errors import ConfigError, SchemaError
from common.keys import KeyKind, Keys
from common.schema import Pose, SensorInfo

__all__ = ["TYPE_BY_KIND", "decode_on_key", "placed_pose", "type_for_key"]

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
