"""``agent foxglove``: a WebSocket client (Foxglove's protocol) sees the scene channels and receives tracks."""

from __future__ import annotations

import asyncio
import base64
import importlib.util
import json
import struct
import sys
import time
from typing import Any

import pytest

from common.codec import encode
from common.keys import Keys
from common.schema import Track, TrackSet
from tests.support import client_session, decode_protobuf, free_port, skip_or_fail, wait_for_liveliness

pytestmark = pytest.mark.integration

K = Keys("pano")


def _trackset(i: int) -> TrackSet:
    t = Track(manager_id="mgr1", seq=i, stamp_ns=time.time_ns(), track_id="mgr1-1", x_m=1.0, y_m=2.0, height_m=1.7,
              vx_mps=0.5, vy_mps=0.0, cov_xx_m2=0.01, cov_xy_m2=0.0, cov_yy_m2=0.01, state="confirmed",
              method="triangulation")  # fmt: skip
    return TrackSet(manager_id="mgr1", seq=i, stamp_ns=t.stamp_ns, tracks=[t])


async def _client(port: int, publish: Any) -> tuple[dict[str, Any], dict[str, Any]]:
    import websockets

    async with websockets.connect(f"ws://127.0.0.1:{port}", subprotocols=["foxglove.sdk.v1"]) as ws:  # type: ignore[list-item]
        channels: dict[str, Any] = {}
        info: dict[str, Any] = {}
        deadline = time.monotonic() + 20
        while "/scene/tracks" not in channels and time.monotonic() < deadline:
            msg = json.loads(await asyncio.wait_for(ws.recv(), 20))
            if msg["op"] == "serverInfo":
                info = msg
            elif msg["op"] == "advertise":
                channels.update({c["topic"]: c for c in msg["channels"]})
        scene = channels["/scene/tracks"]
        await ws.send(json.dumps({"op": "subscribe", "subscriptions": [{"id": 1, "channelId": scene["id"]}]}))
        while time.monotonic() < deadline:
            publish()
            try:
                frame = await asyncio.wait_for(ws.recv(), 0.5)
            except TimeoutError:
                continue
            if isinstance(frame, bytes) and frame[0] == 1:  # MessageData: opcode, subscription id, log time, payload
                (sub_id,) = struct.unpack_from("<I", frame, 1)
                assert sub_id == 1
                payload = frame[1 + 4 + 8 :]
                assert scene["encoding"] == "protobuf" and scene["schemaEncoding"] == "protobuf"
                return info | {"channels": channels}, decode_protobuf(
                    scene["schemaName"], base64.b64decode(scene["schema"]), payload
                )
        raise AssertionError("no message data from the Foxglove server")


def test_foxglove_server_streams_the_track_scene(router: Any, spawn: Any) -> None:
    if importlib.util.find_spec("websockets") is None:
        skip_or_fail("websockets is not installed")
    port = free_port()
    spawn([sys.executable, "-m", "user_agent", "foxglove", "--port", str(port), "--connect", router.endpoint,
           "--agent-id", "fox"], name="foxglove")  # fmt: skip
    with client_session(router.endpoint) as s:
        wait_for_liveliness(s, K.agent("fox"), timeout_s=20)
        seq = iter(range(10_000))
        info, scene = asyncio.run(_client(port, lambda: s.put(K.tracks(), encode(_trackset(next(seq))))))
    assert info["name"] == "panostereo"
    schemas = {t: c["schemaName"] for t, c in info["channels"].items()}
    assert schemas["/scene/tracks"] == "foxglove.SceneUpdate" and schemas["/tf"] == "foxglove.FrameTransform"
    (entity,) = scene.entities
    assert entity.id == "track/mgr1-1" and entity.frame_id == "world"
    assert entity.cylinders[0].pose.position.x == 1.0
