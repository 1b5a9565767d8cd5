"""Write the golden wire payloads under tests/data/golden/ (run once; the bytes are committed).

    .venv/bin/python tests/data/make_golden.py

The committed ``*.msgpack`` files are what version 1 of the wire format
looked like; ``tests/unit/common/test_codec.py`` checks that they keep
decoding to exactly :data:`GOLDEN`. Re-run this script only when adding a
message type, never to "fix" a failing golden test: a golden payload that
stops decoding means old senders would be cut off.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from common.codec import encode
from common.schema import (
    Blob,
    Features,
    ManagerStatus,
    NodeStatus,
    PairChoice,
    PairEntry,
    PanoramicModel,
    PinholeModel,
    Pose,
    PtzCommand,
    PtzReply,
    PtzRequest,
    PtzState,
    SensorInfo,
    Sighting,
    Track,
    TrackSet,
    ViewPlan,
)

GOLDEN_DIR = Path(__file__).resolve().parent / "golden"
STAMP_NS = 1_767_225_600_000_000_000  # 2026-01-01T00:00:00Z

_TRACK = Track(
    manager_id="mgr1",
    seq=41,
    stamp_ns=STAMP_NS,
    track_id="mgr1-3",
    x_m=2.5,
    y_m=-1.25,
    height_m=1.75,
    vx_mps=0.5,
    vy_mps=-0.25,
    cov_xx_m2=0.01,
    cov_xy_m2=-0.002,
    cov_yy_m2=0.02,
    state="confirmed",
    method="triangulation",
    sensors=["pano1", "pano2"],
    predicted_error_m=0.12,
    age_s=4.5,
    hits=60,
    misses=2,
)

GOLDEN: dict[str, object] = {
    "Features": Features(
        sensor_id="pano1",
        seq=1200,
        stamp_ns=STAMP_NS,
        frame_index=1200,
        blobs=[
            Blob(
                local_id=7,
                bearing_rad=0.75,
                width_rad=0.125,
                top_elev_rad=0.25,
                bottom_elev_rad=-0.5,
                bbox_u_px=120.0,
                bbox_v_px=10.0,
                bbox_w_px=24.0,
                bbox_h_px=90.0,
                hist=[0.5, 0.25, 0.25],
                changed_frac=0.8,
                feet_visible=False,
                confidence=0.9,
            )
        ],
        sightings=[
            Sighting(
                target_id="pano2",
                left_rad=-1.0,
                right_rad=-0.875,
                alpha_rad=0.125,
                bearing_rad=-0.9375,
                distance_m=3.2,
                body_radius_m=0.2,
            )
        ],
        processing_ms=12.5,
    ),
    "SensorInfo": SensorInfo(
        sensor_id="pano1",
        seq=3,
        stamp_ns=STAMP_NS,
        kind="panoramic",
        model=PanoramicModel(width_px=1080, height_px=162, f_v_px=171.9, v0_px=90.0, direction=1),
        pose=Pose(x_m=1.0, y_m=2.0, z_m=1.1, yaw_rad=math.pi / 2),
        pose_source="surveyed",
        mobile=True,
        body_radius_m=0.2,
        fps=15.0,
        clock_offset_ns=-1500,
        clock_uncertainty_ns=250_000,
        clock_source="ntp",
        bearing_sigma_rad=0.004,
    ),
    "SensorInfo_pinhole": SensorInfo(
        sensor_id="ptz1",
        seq=1,
        stamp_ns=STAMP_NS,
        kind="ptz",
        model=PinholeModel(
            width_px=640,
            height_px=480,
            k=[500.0, 0.0, 320.0, 0.0, 500.0, 240.0, 0.0, 0.0, 1.0],
            dist=[0.01, -0.002],
            r=[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            t_m=[0.0, 0.0, 2.5],
        ),
    ),
    "NodeStatus": NodeStatus(
        sensor_id="pano1",
        seq=60,
        stamp_ns=STAMP_NS,
        fps=14.8,
        frames=900,
        dropped_frames=3,
        processing_ms=21.0,
        clock_offset_ns=0,
        clock_uncertainty_ns=0,
        clock_source="system",
        decode_errors=1,
        source_state="ok",
        message="",
    ),
    "PtzCommand": PtzCommand(
        manager_id="mgr1",
        seq=5,
        stamp_ns=STAMP_NS,
        sensor_id="ptz1",
        pan_rad=-2.0,
        tilt_rad=0.1,
        zoom=3.0,
        track_id="mgr1-3",
    ),
    "PtzState": PtzState(sensor_id="ptz1", seq=6, stamp_ns=STAMP_NS, pan_rad=-2.0, tilt_rad=0.1, zoom=3.0, moving=True),
    "Track": _TRACK,
    "TrackSet": TrackSet(
        manager_id="mgr1", seq=41, stamp_ns=STAMP_NS, tracks=[_TRACK], sensors_used=["pano1", "pano2"]
    ),
    "PairChoice": PairChoice(
        manager_id="mgr1",
        seq=41,
        stamp_ns=STAMP_NS,
        choices=[
            PairEntry(
                track_id="mgr1-3",
                sensor_a="pano1",
                sensor_b="pano2",
                predicted_error_m=0.12,
                method="size_ratio",
                candidates=3,
            )
        ],
    ),
    "ViewPlan": ViewPlan(
        manager_id="mgr1",
        seq=2,
        stamp_ns=STAMP_NS,
        sensor_id="pano2",
        partner_id="pano1",
        track_id="mgr1-3",
        goal_x_m=3.0,
        goal_y_m=1.5,
        baseline_m=1.8,
        phi1_rad=1.2,
        predicted_error_m=0.05,
        current_error_m=0.3,
    ),
    "ManagerStatus": ManagerStatus(
        manager_id="mgr1",
        seq=10,
        stamp_ns=STAMP_NS,
        tick_ms=4.0,
        tick_p99_ms=9.5,
        tick_rate_hz=15.0,
        sensors_in_use=["pano1", "pano2"],
        sensors_known=["pano1", "pano2", "ptz1"],
        sensors_without_pose=["ptz1"],
        tracks=1,
        decode_errors=0,
        late_msgs=2,
        duplicate_msgs=0,
        out_of_order_msgs=1,
        dropped_msgs=0,
    ),
    "PtzRequest": PtzRequest(
        agent_id="agent1", seq=1, stamp_ns=STAMP_NS, action="acquire", track_id="mgr1-3", priority=5
    ),
    "PtzReply": PtzReply(
        manager_id="mgr1", seq=1, stamp_ns=STAMP_NS, ok=True, track_id="mgr1-3", sensor_id="ptz1", reason="closest free"
    ),
}
"""name -> message; ``golden/<name>.msgpack`` holds ``encode(message)`` as of wire version 1."""


def main() -> int:
    GOLDEN_DIR.mkdir(parents=True, exist_ok=True)
    for name, msg in GOLDEN.items():
        path = GOLDEN_DIR / f"{name}.msgpack"
        path.write_bytes(encode(msg))  # type: ignore[arg-type]
        sys.stdout.write(f"wrote {path.name} ({path.stat().st_size} bytes)\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
