"""Outgoing messages (resource_manager/serve/messages.py): numbers brought inside the schema's own ranges."""

from __future__ import annotations

import math

import msgspec
import numpy as np
import pytest

from common.codec import decode, encode
from common.schema import MAX_SENSORS, MAX_TRACKS, PtzCommand, Track, TrackSet
from resource_manager.serve.messages import ptz_command, track_message, track_set
from resource_manager.serve.ptz import PtzAim
from resource_manager.track.tracker import TrackSnapshot


def _snapshot(x_m: float, vx_mps: float, var_m2: float, sensors: int = 2) -> TrackSnapshot:
    return TrackSnapshot(
        serial=7,
        track_id="",
        x=np.array([x_m, 1.0, vx_mps, 0.0]),
        p_xy=np.array([[var_m2, 0.0], [0.0, var_m2]]),
        height_m=1.7,
        existence=0.9,
        state="confirmed",
        method="triangulation",
        sensors=tuple(f"c{k}" for k in range(sensors)),
        predicted_error_m=0.1,
        born_ns=0,
        t_ns=2_000_000_000,
        hits=3,
        misses=0,
        confirmed=True,
        detected=True,
        placed=True,
        reported=True,
    )


@pytest.mark.parametrize(
    ("x_m", "vx_mps", "var_m2", "want_x", "want_vx"),
    [
        (3.0, 1.0, 0.01, 3.0, 1.0),
        (1e9, -1e9, 1e30, 1e5, -1e3),  # a diverged estimate is published clipped, not refused by the encoder
        (math.nan, 0.0, 0.01, math.nan, 0.0),
    ],
)
def test_a_track_fits_its_schema(x_m: float, vx_mps: float, var_m2: float, want_x: float, want_vx: float) -> None:
    msg = track_message("m1", _snapshot(x_m, vx_mps, var_m2, sensors=MAX_SENSORS + 3), seq=4)
    assert msg.track_id == "m1-t7" and msg.seq == 4 and msg.age_s == 2.0
    assert (math.isnan(msg.x_m) and math.isnan(want_x)) or msg.x_m == want_x
    assert msg.vx_mps == want_vx and len(msg.sensors) == MAX_SENSORS
    if not math.isnan(x_m):
        assert decode(encode(msg), Track) == msg


def test_a_track_set_and_a_ptz_command_are_cut_and_clipped_to_the_schema() -> None:
    tr = track_message("m1", _snapshot(1.0, 0.0, 0.01), seq=1)
    ts = track_set("m1", 1, 5, [tr] * (MAX_TRACKS + 1), ["c0"] * (MAX_SENSORS + 1))
    assert len(ts.tracks) == MAX_TRACKS and len(ts.sensors_used) == MAX_SENSORS
    assert decode(encode(ts), TrackSet) == ts
    cmd = ptz_command("m1", 1, 5, PtzAim("z1", "m1-1", 3 * math.pi, -4.0, 2.0))
    assert cmd.tilt_rad == -math.pi / 2 and -math.pi <= cmd.pan_rad <= math.pi
    assert decode(encode(cmd), PtzCommand) == msgspec.structs.replace(cmd)
