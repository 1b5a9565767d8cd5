"""Outgoing messages (resource_manager/serve/messages.py): numbers brought inside the schema's own ranges."""

from __future__ import annotations

import math

import msgspec
import numpy as np

from common.codec import decode, encode
from common.schema import MAX_SENSORS, MAX_TRACKS, PtzCommand, TrackSet
from resource_manager.serve.messages import ptz_command, track_message, track_set
from resource_manager.serve.ptz import PtzAim
from resource_manager.track.tracker import TrackSnapshot
from tests.unit.resource_manager.synth import snapshot


def _snapshot(x_m: float, vx_mps: float, var_m2: float, sensors: int = 2) -> TrackSnapshot:
    cams = tuple(f"c{k}" for k in range(sensors))
    return snapshot(
        7,
        track_id="",
        x=np.array([x_m, 1.0, vx_mps, 0.0]),
        p_xy=np.array([[var_m2, 0.0], [0.0, var_m2]]),
        existence=0.9,
        state="confirmed",
        method="triangulation",
        sensors=cams,
        views=cams,
        t_ns=2_000_000_000,
        hits=3,
        confirmed=True,
        reported=True,
    )


def test_a_track_set_and_a_ptz_command_are_cut_and_clipped_to_the_schema() -> None:
    tr = track_message("m1", _snapshot(1.0, 0.0, 0.01), seq=1)
    ts = track_set("m1", 1, 5, [tr] * (MAX_TRACKS + 1), ["c0"] * (MAX_SENSORS + 1))
    assert len(ts.tracks) == MAX_TRACKS and len(ts.sensors_used) == MAX_SENSORS
    assert decode(encode(ts), TrackSet) == ts
    cmd = ptz_command("m1", 1, 5, PtzAim("z1", "m1-1", 3 * math.pi, -4.0, 2.0))
    assert cmd.tilt_rad == -math.pi / 2 and -math.pi <= cmd.pan_rad <= math.pi
    assert decode(encode(cmd), PtzCommand) == msgspec.structs.replace(cmd)
