"""Sensor-node processes against a real router: sim, detections and PTZ sources from TOML configs.

Each test starts the node as its own process (``python -m sensor_node``,
``sensor-node``, ``panostereo node``), waits for its liveliness token, reads
Features and NodeStatus on the documented keys, queries SensorInfo, and stops
it with SIGTERM, expecting a clean exit and the token gone.
"""

from __future__ import annotations

import json
import math
import signal
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from common.cameras import PinholeCamera
from common.codec import decode
from common.keys import Keys
from common.schema import Features, NodeStatus, PtzCommand, PtzState, SensorInfo
from common.session import MSGPACK
from common.transport import Inbox, TypedPublisher
from tests.support import (
    FakeNtpServer,
    RouterProcess,
    client_session,
    wait_for,
    wait_for_liveliness,
    wait_for_no_liveliness,
)

pytestmark = pytest.mark.integration

SITE = """
[site]
name = "it"
fps = 10.0
seed = 4

[world]
people = 2
pause_prob = 0.0

[[camera]]
id = "pano1"
x_m = 2.5
y_m = 3.0
band_rgb = [220, 40, 40]

[[camera]]
id = "pano2"
x_m = 5.5
y_m = 3.0
band_rgb = [40, 80, 220]

[[camera]]
id = "ptz1"
kind = "ptz"
x_m = 7.8
y_m = 5.8
height_m = 2.5
body_radius_m = 0.0
image_size = [320, 240]
pan_deg = -140.0
tilt_deg = -20.0
"""


def _node_config(tmp_path: Path, router: RouterProcess, sid: str, source: str, extra: str = "", node: str = "") -> Path:
    p = tmp_path / f"{sid}.toml"
    p.write_text(
        f'[node]\nid = "{sid}"\nprefix = "it"\n{node}\n[zenoh]\nconnect = ["{router.endpoint}"]\n\n'
        f"[source]\n{source}\n{extra}"
    )
    return p


def _query_info(session: Any, key: str) -> SensorInfo:
    def ask() -> SensorInfo | None:
        for r in session.get(key, timeout=2.0):
            if r.ok is not None:
                assert str(r.ok.encoding).startswith(MSGPACK)
                return decode(r.ok.payload.to_bytes(), SensorInfo)
        return None

    info: SensorInfo = wait_for(ask, 10.0, f"SensorInfo on {key}")
    return info


def _stop_cleanly(proc: Any, session: Any, token: str) -> None:
    proc.signal(signal.SIGTERM)
    assert proc.wait(15.0) == 0, proc.log()
    wait_for_no_liveliness(session, token, 5.0)
    assert "Traceback" not in proc.stderr_text()


def test_sim_node_publishes_features_info_status(tmp_path: Path, router: RouterProcess, spawn: Any) -> None:
    (tmp_path / "site.toml").write_text(SITE)
    cfg = _node_config(
        tmp_path,
        router,
        "pano1",
        'kind = "sim"\nsite = "site.toml"\nfps = 10.0',
        '\n[[body]]\nid = "pano2"\nband_rgb = [40, 80, 220]\nradius_m = 0.18\n',
        node="mobile = true\n",
    )
    keys = Keys("it")
    with client_session(router.endpoint) as s:
        features = Inbox(s, keys.sensor_features("pano1"), Features)
        status = Inbox(s, keys.sensor_status("pano1"), NodeStatus)
        proc = spawn(
            [sys.executable, "-m", "sensor_node", "--config", cfg], env={"PANOSTEREO_EPOCH_NS": str(time.time_ns())}
        )
        wait_for_liveliness(s, keys.sensor("pano1"), 20.0)
        info = _query_info(s, keys.sensor_info("pano1"))
        assert info.sensor_id == "pano1" and info.kind == "panoramic" and info.pose_source == "mutual"
        # A robot's x, y and yaw come from mutual calibration; its camera height from its camera model.
        assert info.pose is not None and info.pose.z_m == pytest.approx(1.1)
        assert info.model.width_px == 1080 and info.clock_source == "system"
        got: list[Features] = []

        def enough() -> bool:
            got.extend(r.msg for r in features.drain())
            return len(got) >= 45 and any(f.sightings for f in got)

        wait_for(enough, 30.0, "45 Features with a sighting of pano2")
        seqs = [f.seq for f in got]
        assert seqs == sorted(seqs) and len(set(seqs)) == len(seqs)
        now = time.time_ns()
        assert all(abs(now - f.stamp_ns) < 30e9 and f.sensor_id == "pano1" for f in got)
        sightings = [x for f in got for x in f.sightings]
        assert {x.target_id for x in sightings} == {"pano2"}
        # Most sightings range pano2 right; a person walking in front of its band shifts some (which frames those
        # are depends on when the node started: the machine's load), so the median is what is held.
        assert abs(float(np.median([x.distance_m for x in sightings])) - 3.0) < 0.15, sightings
        assert any(f.blobs for f in got[-10:]), "two people walking in the room: someone is seen"
        statuses: list[NodeStatus] = []

        def ok_status() -> bool:
            statuses.extend(r.msg for r in status.drain())
            return any(m.frames > 0 and not m.message for m in statuses)

        wait_for(ok_status, 10.0, "a NodeStatus with frames")
        st = [m for m in statuses if m.frames > 0]
        assert st[-1].source_state == "ok" and st[-1].fps > 0 and st[-1].dropped_msgs == 0
        # While the background is learnt (no blobs yet) the status says so.
        assert any(m.message.startswith("learning the background") for m in statuses)
        _stop_cleanly(proc, s, keys.sensor("pano1"))


def _calibration(tmp_path: Path) -> tuple[Path, PinholeCamera]:
    # A camera at (0, -4, 2.5) m looking along +y, tilted 20 degrees down.
    tilt = math.radians(-20.0)
    r = np.array([[1.0, 0.0, 0.0], [0.0, -math.sin(tilt), -math.cos(tilt)], [0.0, math.cos(tilt), -math.sin(tilt)]])
    center = np.array([0.0, -4.0, 2.5])
    t = -r @ center
    d = {
        "model": "pinhole",
        "image_size": [1920, 1080],
        "K": [[1700.0, 0.0, 960.0], [0.0, 1700.0, 540.0], [0.0, 0.0, 1.0]],
        "dist": [0.0, 0.0, 0.0, 0.0],
        "R": r.tolist(),
        "t": t.tolist(),
    }
    p = tmp_path / "calib.json"
    p.write_text(json.dumps(d))
    return p, PinholeCamera.from_calibration(d, str(p))


def test_detection_file_node(tmp_path: Path, router: RouterProcess, spawn: Any) -> None:
    calib, cam = _calibration(tmp_path)
    assert np.allclose(cam.center_world, [0.0, -4.0, 2.5])
    # A person standing at (1, 2) m, 1.7 m tall, seen in every frame; a second one without an id.
    feet, head = np.array([[1.0, 2.0, 0.0]]), np.array([[1.0, 2.0, 1.7]])
    (uf, vf), (_, vh) = cam.project(feet)[0][0], cam.project(head)[0][0]
    w = 60.0
    lines = []
    for k in range(1, 400):
        lines.append(f"{k},7,{uf - w / 2:.2f},{vh:.2f},{w:.2f},{vf - vh:.2f},0.9,-1,-1,-1")
        lines.append(f"{k},-1,100,300,50,150,0.8,-1,-1,-1")
    det = tmp_path / "det.txt"
    det.write_text("\n".join(lines) + "\n")
    cfg = _node_config(
        tmp_path, router, "c1", f'kind = "detections"\nfile = "det.txt"\ncalibration = "{calib.name}"\nfps = 5.0'
    )
    keys = Keys("it")
    with client_session(router.endpoint) as s:
        features = Inbox(s, keys.sensor_features("c1"), Features)
        status = Inbox(s, keys.sensor_status("c1"), NodeStatus)
        proc = spawn(
            [sys.executable, "-m", "panostereo", "node", "--config", cfg],
            env={"PANOSTEREO_EPOCH_NS": str(time.time_ns())},
        )
        wait_for_liveliness(s, keys.sensor("c1"), 20.0)
        info = _query_info(s, keys.sensor_info("c1"))
        assert info.kind == "pinhole" and info.pose is not None and info.pose.yaw_rad == 0.0
        assert (info.pose.x_m, info.pose.y_m, info.pose.z_m) == pytest.approx((0.0, -4.0, 2.5), abs=1e-6)
        got: list[Features] = wait_for(lambda: [r.msg for r in features.drain()], 10.0, "Features from c1")
        f = got[0]
        assert len(f.blobs) == 2
        person = next(b for b in f.blobs if b.local_id == 7)
        assert person.bearing_rad == pytest.approx(math.atan2(2.0 + 4.0, 1.0), abs=1e-3)  # feet azimuth from the centre
        assert person.top_elev_rad == pytest.approx(math.atan2(1.7 - 2.5, math.hypot(1.0, 6.0)), abs=1e-3)
        assert person.hist == [] and person.confidence == pytest.approx(0.9)
        width_m = 2 * math.hypot(1.0, 6.0) * math.tan(person.width_rad / 2)
        assert 0.1 < width_m < 0.6
        st = wait_for(lambda: [r.msg for r in status.drain() if r.msg.frames > 0], 10.0, "NodeStatus")
        assert st[-1].source_state == "ok"
        _stop_cleanly(proc, s, keys.sensor("c1"))


def test_ptz_node_obeys_commands(tmp_path: Path, router: RouterProcess, spawn: Any) -> None:
    (tmp_path / "site.toml").write_text(SITE)
    cfg = _node_config(
        tmp_path,
        router,
        "ptz1",
        'kind = "sim"\nsite = "site.toml"\nfps = 5.0',
        "\n[pose]\nx_m = 7.8\ny_m = 5.8\nz_m = 2.5\n",
    )
    keys = Keys("it")
    exe = Path(sys.executable).parent / "sensor-node"
    with client_session(router.endpoint) as s:
        states = Inbox(s, keys.sensor_ptz_state("ptz1"), PtzState)
        features = Inbox(s, keys.sensor_features("ptz1"), Features)
        proc = spawn([exe if exe.exists() else sys.executable, *([] if exe.exists() else ["-m", "sensor_node"]),
                           "--config", cfg])  # fmt: skip
        wait_for_liveliness(s, keys.sensor("ptz1"), 20.0)
        info = _query_info(s, keys.sensor_info("ptz1"))
        assert info.kind == "ptz" and info.pose is not None and info.pose.yaw_rad == 0.0
        wait_for(features.drain, 15.0, "Features from ptz1")
        pub = TypedPublisher(s, keys.sensor_ptz("ptz1"), reliable_block=True)
        cmd = PtzCommand(
            manager_id="m1", seq=0, stamp_ns=time.time_ns(), sensor_id="ptz1", pan_rad=-2.0, tilt_rad=-0.3, zoom=2.0
        )
        seen: list[PtzState] = []

        def arrived() -> bool:
            pub.put(cmd)  # repeated: the node may have subscribed after the first put
            seen.extend(r.msg for r in states.drain())
            last = seen[-1] if seen else None
            return last is not None and not last.moving and abs(last.pan_rad + 2.0) < 1e-3 and last.zoom == 2.0

        wait_for(arrived, 15.0, "PtzState at the commanded pan/zoom")
        # SensorInfo's pinhole model follows the head (put on change, and the queryable answers it).
        info2 = wait_for(
            lambda: (i := _query_info(s, keys.sensor_info("ptz1"))).model != info.model and i, 10.0, "a new model"
        )
        cam2 = PinholeCamera.from_model(info2.model)
        az, _ = cam2.bearing_elevation(np.array([[159.5, 119.5]]))
        assert az[0] == pytest.approx(-2.0, abs=1e-3)
        pub.close()
        _stop_cleanly(proc, s, keys.sensor("ptz1"))


def test_opencv_node_reports_a_failing_camera_and_keeps_retrying(
    tmp_path: Path, router: RouterProcess, spawn: Any
) -> None:
    missing = tmp_path / "no-such-camera.mp4"
    camera = (
        '\n[camera]\nmodel = "panoramic"\ncenter_px = [388.0, 284.0]\nradial_poly = [254.0, -1.06, 0.0008]\n'
        "f_v_px = 234.0\nv0_px = 84.7\n"
    )
    source = f'kind = "opencv"\nuri = "{missing}"\nreconnect_min_s = 0.2\nreconnect_max_s = 0.4'
    cfg = _node_config(tmp_path, router, "cam9", source, camera)
    keys = Keys("it")
    with client_session(router.endpoint) as s:
        status = Inbox(s, keys.sensor_status("cam9"), NodeStatus)
        proc = spawn([sys.executable, "-m", "sensor_node", "--config", cfg])
        wait_for_liveliness(s, keys.sensor("cam9"), 20.0)
        seen: list[NodeStatus] = []

        def retrying() -> bool:
            seen.extend(r.msg for r in status.drain())
            return len([m for m in seen if m.source_state == "reconnecting"]) >= 2

        wait_for(retrying, 15.0, "two NodeStatus saying the source is reconnecting")
        bad = [m for m in seen if m.source_state == "reconnecting"]
        assert str(missing) in bad[-1].message and "retrying" in bad[-1].message
        assert all(m.frames == 0 for m in seen)
        info = _query_info(s, keys.sensor_info("cam9"))
        assert info.kind == "panoramic" and info.model.width_px == 1080
        _stop_cleanly(proc, s, keys.sensor("cam9"))


def test_stamps_are_on_the_ntp_corrected_clock(tmp_path: Path, router: RouterProcess, spawn: Any) -> None:
    calib, _ = _calibration(tmp_path)
    det = tmp_path / "det.txt"
    det.write_text("".join(f"{k},1,900,400,60,200,0.9\n" for k in range(1, 200)))
    source = f'kind = "detections"\nfile = "det.txt"\ncalibration = "{calib.name}"\nfps = 5.0'
    keys = Keys("it")
    with FakeNtpServer(skew_s=3.0) as ntp, client_session(router.endpoint) as s:
        clock = f'\n[clock]\nntp_server = "127.0.0.1"\nntp_port = {ntp.port}\nsamples = 4\n'
        cfg = _node_config(tmp_path, router, "c2", source, clock)
        features = Inbox(s, keys.sensor_features("c2"), Features)
        status = Inbox(s, keys.sensor_status("c2"), NodeStatus)
        proc = spawn([sys.executable, "-m", "sensor_node", "--config", cfg])  # epoch: the node's (NTP) start
        wait_for_liveliness(s, keys.sensor("c2"), 20.0)
        info = _query_info(s, keys.sensor_info("c2"))
        assert info.clock_source == "ntp" and abs(info.clock_offset_ns - 3e9) < 0.1e9
        got: list[Features] = wait_for(lambda: [r.msg for r in features.drain()], 10.0, "Features from c2")
        lead_s = (got[-1].stamp_ns - time.time_ns()) / 1e9
        assert 2.0 < lead_s < 4.0, f"stamps should be ~3 s ahead of this host's clock, got {lead_s:.2f} s"
        st = wait_for(lambda: [r.msg for r in status.drain() if r.msg.clock_source == "ntp"], 10.0, "NTP status")
        assert abs(st[-1].clock_offset_ns - 3e9) < 0.1e9 and st[-1].clock_uncertainty_ns > 0
        _stop_cleanly(proc, s, keys.sensor("c2"))
