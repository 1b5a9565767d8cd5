"""``agent foxglove``: serve the live 3D scene over Foxglove's WebSocket protocol.

Open Foxglove, "Open connection", ``ws://HOST:PORT``, and add a 3D panel: the
same channels as a recording — ``/scene/tracks`` and ``/scene/cameras``
(``foxglove.SceneUpdate``), ``/tf`` (``foxglove.FrameTransform``), on
foxglove-sdk's typed channels, and ``/tracks`` (the TrackSet as JSON with its
schema). The WebSocket server is foxglove-sdk's (subprotocol
``foxglove.sdk.v1``); zenoh callbacks only enqueue (common.transport), the
bridge's own loop converts and logs.
"""

from __future__ import annotations

import json
import logging
from typing import Any

import foxglove as fg
import msgspec
from foxglove.channels import FrameTransformChannel, SceneUpdateChannel

from common.codec import decode
from common.errors import ConfigError, SchemaError
from common.keys import Keys
from common.schema import ManagerStatus, SensorInfo, TrackSet
from common.transport import Inbox
from user_agent.foxglove import CameraPlacements, tracks_scene

__all__ = ["FoxgloveBridge"]

logger = logging.getLogger(__name__)


class FoxgloveBridge:
    """Zenoh tracks, sensor info and the managers' camera poses -> a Foxglove WebSocket server.

    Mobile cameras appear where the manager's mutual calibration places them (``ManagerStatus.poses``).

    Args:
        session: an open zenoh session.
        keys: the site's keys.
        host, port: where the WebSocket server listens (port 0: any free port, see :attr:`port`).
    """

    def __init__(self, session: Any, keys: Keys, host: str = "127.0.0.1", port: int = 8765) -> None:
        self._session = session
        self._keys = keys
        self._ctx = fg.Context()
        try:
            self.server = fg.start_server(name="panostereo", host=host, port=port, context=self._ctx)
        except Exception as err:  # address in use, bad host
            raise ConfigError(f"cannot start the Foxglove server on {host}:{port}: {err}") from err
        self._tracks = SceneUpdateChannel("/scene/tracks", context=self._ctx)
        self._cameras = SceneUpdateChannel("/scene/cameras", context=self._ctx)
        self._tf = FrameTransformChannel("/tf", context=self._ctx)
        raw_schema = fg.Schema(
            name="pano.TrackSet", encoding="jsonschema", data=json.dumps(msgspec.json.schema(TrackSet)).encode()
        )
        self._raw = fg.Channel("/tracks", schema=raw_schema, message_encoding="json", context=self._ctx)
        self._placements = CameraPlacements()
        self._in_tracks = Inbox(session, keys.tracks(), TrackSet, capacity=64)
        self._in_info = Inbox(session, keys.all_sensor_info, SensorInfo, capacity=64)
        self._in_status = Inbox(session, keys.all_manager_status, ManagerStatus, capacity=16)
        self.messages = 0

    @property
    def port(self) -> int:
        return int(self.server.port)

    def refresh_sensors(self, timeout_s: float = 1.0) -> None:
        """Query every sensor's info (it is put only on change, so a late bridge asks)."""
        for reply in self._session.get(self._keys.all_sensor_info, timeout=timeout_s):
            if reply.ok is None:
                continue
            try:
                self._place(decode(reply.ok.payload.to_bytes(), SensorInfo))
            except SchemaError as err:
                logger.warning("bad SensorInfo reply dropped: %s", err)

    def _place(self, msg: SensorInfo | ManagerStatus) -> None:
        """Log the cameras' scene and transforms a SensorInfo or a manager's status changes."""
        scene, tfs = self._placements.update(msg, msg.stamp_ns)
        if scene is None:
            return
        self._cameras.log(scene, log_time=msg.stamp_ns)
        for tf in tfs:
            self._tf.log(tf, log_time=msg.stamp_ns)
        self.messages += 1

    def pump(self, timeout_s: float = 0.1) -> int:
        """Forward what arrived (waits up to ``timeout_s`` for a TrackSet); returns messages logged."""
        before = self.messages
        for r in self._in_info.drain():
            self._place(r.msg)
        for rs in self._in_status.drain():
            self._place(rs.msg)
        first = self._in_tracks.get(timeout_s)
        for rt in ([first] if first is not None else []) + self._in_tracks.drain():
            ts = rt.msg
            self._tracks.log(tracks_scene(ts, self._placements.camera_xyz), log_time=ts.stamp_ns)
            self._raw.log(msgspec.to_builtins(ts), log_time=ts.stamp_ns)
            self.messages += 2
        return self.messages - before

    def close(self) -> None:
        self._in_tracks.close()
        self._in_info.close()
        self._in_status.close()
        self.server.stop()
