"""Read an MCAP recording made by :mod:`user_agent.record` back into typed messages."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

from mcap.exceptions import McapError
from mcap.reader import make_reader

from common.errors import ConfigError
from common.schema import Features, ManagerStatus, NodeStatus, PairChoice, SensorInfo, TrackSet, ViewPlan
from user_agent.messages import decode_on_key
from user_agent.record import META_NAME, keys_for

__all__ = ["RawSample", "Recording", "iter_raw", "load_recording", "read_metadata"]


@dataclass(frozen=True, slots=True)
class RawSample:
    """One recorded zenoh sample."""

    key: str
    data: bytes
    log_time_ns: int
    """Local arrival time when recorded."""


def _open(path: str | Path) -> Path:
    p = Path(path)
    if not p.is_file():
        raise ConfigError(f"{p}: no such recording")
    return p


def read_metadata(path: str | Path) -> dict[str, str]:
    """The ``panostereo*`` metadata records merged (site, epoch_ns, fps, room, score_from_ns) or {}."""
    p = _open(path)
    out: dict[str, str] = {}
    try:
        with p.open("rb") as fh:
            for rec in make_reader(fh).iter_metadata():
                if rec.name == META_NAME or rec.name.startswith(META_NAME + "."):
                    out.update(rec.metadata)
    except (McapError, ValueError, EOFError, OSError) as err:
        raise ConfigError(f"{p}: not a readable MCAP recording: {err}") from err
    return out


def iter_raw(path: str | Path) -> Iterator[RawSample]:
    """Every raw sample in log-time order."""
    p = _open(path)
    try:
        with p.open("rb") as fh:
            reader = make_reader(fh)
            for _schema, channel, message in reader.iter_messages(log_time_order=True):
                if channel.metadata.get("kind") != "raw":
                    continue
                key = channel.metadata.get("zenoh_key", channel.topic)
                yield RawSample(key, bytes(message.data), int(message.log_time))
    except (McapError, ValueError, EOFError) as err:
        raise ConfigError(f"{p}: not a readable MCAP recording: {err}") from err


@dataclass
class Recording:
    """The decoded content of a recording that evaluation and plotting need."""

    metadata: dict[str, str]
    tracksets: list[TrackSet] = field(default_factory=list)
    sensor_infos: dict[str, SensorInfo] = field(default_factory=dict)
    """Latest SensorInfo per sensor."""
    pairs: list[PairChoice] = field(default_factory=list)
    plans: list[ViewPlan] = field(default_factory=list)
    node_status: dict[str, NodeStatus] = field(default_factory=dict)
    manager_status: dict[str, ManagerStatus] = field(default_factory=dict)
    mutual_paths: dict[str, list[tuple[float, float]]] = field(default_factory=dict)
    """Where the managers placed each mobile camera by mutual calibration, in status order."""
    frames: dict[str, int] = field(default_factory=dict)
    """Features recorded per sensor (the cameras that published)."""
    samples: int = 0
    invalid: int = 0
    first_log_ns: int = 0
    last_log_ns: int = 0

    def meta_float(self, name: str, default: float) -> float:
        try:
            return float(self.metadata[name])
        except (KeyError, ValueError):
            return default

    def meta_int(self, name: str, default: int) -> int:
        try:
            return int(self.metadata[name])
        except (KeyError, ValueError):
            return default


def load_recording(path: str | Path) -> Recording:
    """Decode a recording's TrackSets, SensorInfos, pairs, plans and statuses.

    Raises:
        ConfigError: if the file is missing or not an MCAP file.
    """
    rec = Recording(metadata=read_metadata(path))
    for s in iter_raw(path):
        rec.samples += 1
        rec.first_log_ns = rec.first_log_ns or s.log_time_ns
        rec.last_log_ns = s.log_time_ns
        keys = keys_for(s.key)
        msg = decode_on_key(keys, s.key, s.data) if keys is not None else None
        if msg is None:
            rec.invalid += 1
        elif isinstance(msg, TrackSet):
            rec.tracksets.append(msg)
        elif isinstance(msg, Features):
            rec.frames[msg.sensor_id] = rec.frames.get(msg.sensor_id, 0) + 1
        elif isinstance(msg, SensorInfo):
            rec.sensor_infos[msg.sensor_id] = msg
        elif isinstance(msg, PairChoice):
            rec.pairs.append(msg)
        elif isinstance(msg, ViewPlan):
            rec.plans.append(msg)
        elif isinstance(msg, NodeStatus):
            rec.node_status[msg.sensor_id] = msg
        elif isinstance(msg, ManagerStatus):
            rec.manager_status[msg.manager_id] = msg
            for est in msg.poses:
                if est.source == "mutual":
                    rec.mutual_paths.setdefault(est.sensor_id, []).append((est.pose.x_m, est.pose.y_m))
    rec.tracksets.sort(key=lambda t: t.stamp_ns)
    return rec
