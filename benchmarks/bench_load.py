"""Load benchmark (issue 8): 16 camera streams at 30 Hz through one resource manager for 60 s.

Usage::

    python -m benchmarks.bench_load [--sensors 16] [--fps 30] [--duration 60] [--people 6] [--out FILE]
    python -m benchmarks.bench_load --schedules watermark  # only the event-driven schedule
    python -m benchmarks.bench_load --nodes real      # one real `panostereo node` process per camera

What runs (all real processes on loopback, multicast scouting off):

* a ``panostereo router``;
* one ``panostereo manager`` (its config written to a temp dir: prefix ``bench``, at most 10 fusions/s);
* a *fleet* process (this module, ``fleet`` sub-command) that plays N panoramic sensor nodes at
  ``fps``: for each it declares the liveliness token, serves and puts a ``SensorInfo`` with a
  surveyed pose, puts ``NodeStatus`` at 1 Hz and one ``Features`` message per frame. The blobs
  are what a panoramic node would report for the people of a small simulated room (bearing,
  angular width, top and bottom elevation, bounding box, a per-person colour histogram), with
  0.2 deg bearing noise and frames of different sensors out of phase, as free-running cameras
  are. (Rendering and segmenting 16 x 30 panoramas per second would need ~16 cores; this
  exercises everything downstream of the image pipeline: transport, ingest, alignment, pair
  choice, matching, localisation, tracking, publication.) Capture stamps are the fleet's clock
  at the frame time;
* or, with ``--nodes real``, one real ``panostereo node`` process per camera, each playing a
  detection file of the same room (a pinhole camera at the same place looking at the room's
  centre; ``write_detection_cameras``): the real node start-up, pacing, session and publication;
* the user agent: this process, subscribed to ``{root}/tracks``; for every TrackSet it notes the
  arrival time.

The manager runs once per ``--schedules`` entry, one after the other in the same invocation: ``watermark``
(event-driven: an instant is fused as soon as every camera has a frame at or after it, or missed its deadline)
and ``fixed`` (the old rule: ``now - latency_ms`` on a ``rate_hz`` timer), so the two are compared on the same
machine under the same load.

Figures (one JSON object on stdout, and in ``--out``), per schedule under ``runs``:

* ``latency_ms`` p50/p90/p99/max: agent arrival time minus the TrackSet's fusion instant, i.e. from capture
  (frames are interpolated to that instant) to the user agent, every wait included (goal, watermark: p50 <= 50
  ms, p99 <= 100 ms);
* ``latency_breakdown_ms``: medians of the manager's ManagerStatus.latency (node processing, transport, waiting
  for the watermark, fusion, publish) and the agent's own publish -> arrival;
* drops: frames sent by the fleet and received by the manager (``frames_lost``, goal 0), the manager's
  ``dropped_msgs``, ``late_msgs``, missed deadlines, ``decode_errors``, and TrackSets lost on the way to the
  agent (gaps in ``seq``); ``tick_rate_hz_achieved`` against the configured maximum;
* accuracy: each confirmed track's distance to the nearest simulated person (scoring only: nothing of it goes
  to the manager), to compare the schedules;
* memory: the manager's RSS (``/proc/<pid>/status``) sampled every second; growth from the first sample after
  the warm-up to the last (goal: flat).

``targets`` says which goals the watermark run met.
"""

from __future__ import annotations

import argparse
import itertools
import json
import logging
import math
import os
import random
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from common.codec import decode, encode
from common.keys import Keys
from common.schema import Blob, Features, ManagerStatus, NodeStatus, PanoramicModel, Pose, SensorInfo, TrackSet
from common.session import MSGPACK, SessionSettings, open_session

logger = logging.getLogger(__name__)

REPO = Path(__file__).resolve().parent.parent

# A panorama like design_pal's: 1080 x 162 px covering -15..+20 deg of elevation.
PANO_W_PX = 1080
PANO_H_PX = 162
F_V_PX = PANO_H_PX / (math.tan(math.radians(20.0)) + math.tan(math.radians(15.0)))
V0_PX = F_V_PX * math.tan(math.radians(20.0))
ELEV_MIN_RAD = math.radians(-15.0)
BODY_RADIUS_M = 0.22
HIST_BINS = 64
MAX_RANGE_M = 12.0


# ---------------------------------------------------------------------------
# The simulated room: people walking, cameras around it
# ---------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Walker:
    """A person walking back and forth between two points of the room at constant speed."""

    person_id: int
    x0_m: float
    y0_m: float
    x1_m: float
    y1_m: float
    speed_mps: float
    height_m: float
    phase_s: float
    hist: tuple[float, ...]

    def at(self, t_s: float) -> tuple[float, float]:
        length = math.hypot(self.x1_m - self.x0_m, self.y1_m - self.y0_m)
        period = 2 * length / self.speed_mps
        s = ((t_s + self.phase_s) % period) * self.speed_mps
        f = s / length if s <= length else 2 - s / length
        return self.x0_m + f * (self.x1_m - self.x0_m), self.y0_m + f * (self.y1_m - self.y0_m)


@dataclass(frozen=True, slots=True)
class Cam:
    sensor_id: str
    x_m: float
    y_m: float
    z_m: float
    yaw_rad: float


def make_room(sensors: int, people: int, seed: int, room_m: float = 10.0) -> tuple[list[Cam], list[Walker]]:
    """Cameras evenly on a circle around a square room, people on random straight beats inside it."""
    rng = random.Random(seed)
    cams = []
    for i in range(sensors):
        a = 2 * math.pi * i / sensors
        r = 0.45 * room_m
        cams.append(
            Cam(
                f"s{i:02d}",
                room_m / 2 + r * math.cos(a),
                room_m / 2 + r * math.sin(a),
                1.1 + 0.1 * (i % 3),
                math.remainder(rng.uniform(-math.pi, math.pi), 2 * math.pi),
            )
        )
    rng = random.Random(f"people-{seed}")  # the people do not depend on how many cameras watch them
    walkers = []
    for p in range(people):
        raw = [rng.random() ** 3 for _ in range(HIST_BINS)]
        total = sum(raw)
        walkers.append(
            Walker(
                p,
                rng.uniform(2, room_m - 2),
                rng.uniform(2, room_m - 2),
                rng.uniform(2, room_m - 2),
                rng.uniform(2, room_m - 2),
                rng.uniform(0.5, 1.3),
                rng.uniform(1.55, 1.9),
                rng.uniform(0, 20),
                tuple(v / total for v in raw),
            )
        )
    return cams, walkers


def _wrap(a: float) -> float:
    return math.remainder(a, 2 * math.pi)


def observe(
    cam: Cam, walkers: list[Walker], t_s: float, rng: random.Random, sigma_rad: float, max_range_m: float = MAX_RANGE_M
) -> list[Blob]:
    """The blobs a panoramic node at ``cam`` would report at world time ``t_s`` (people within ``max_range_m``)."""
    blobs = []
    for w in walkers:
        x, y = w.at(t_s)
        d = math.hypot(x - cam.x_m, y - cam.y_m)
        if d < 0.5 or d > max_range_m:
            continue
        bearing = _wrap(math.atan2(y - cam.y_m, x - cam.x_m) - cam.yaw_rad + rng.gauss(0.0, sigma_rad))
        width = 2 * math.atan(BODY_RADIUS_M / d)
        top = math.atan((w.height_m - cam.z_m) / d) + rng.gauss(0.0, sigma_rad)
        bottom = math.atan(-cam.z_m / d)
        feet = bottom >= ELEV_MIN_RAD
        bottom = max(bottom, ELEV_MIN_RAD)
        u = (bearing % (2 * math.pi)) / (2 * math.pi) * PANO_W_PX
        w_px = width / (2 * math.pi) * PANO_W_PX
        v_top = V0_PX - F_V_PX * math.tan(top)
        v_bot = V0_PX - F_V_PX * math.tan(bottom)
        noisy = [max(0.0, h * (1 + rng.gauss(0.0, 0.05))) for h in w.hist]
        total = sum(noisy) or 1.0
        blobs.append(
            Blob(
                local_id=w.person_id,
                bearing_rad=bearing,
                width_rad=width,
                top_elev_rad=top,
                bottom_elev_rad=bottom,
                bbox_u_px=u - w_px / 2,
                bbox_v_px=v_top,
                bbox_w_px=w_px,
                bbox_h_px=max(0.0, v_bot - v_top),
                hist=[min(1.0, v / total) for v in noisy],
                feet_visible=feet,
            )
        )
    return blobs


# ---------------------------------------------------------------------------
# Detection cameras: real sensor-node processes without rendering (for fault tests)
# ---------------------------------------------------------------------------

DET_W_PX = 640
DET_H_PX = 480
DET_F_PX = 420.0


def look_at(center: tuple[float, float, float], target: tuple[float, float, float]) -> list[list[float]]:
    """World-to-camera rotation (OpenCV axes: x right, y down, z forward) of a camera at ``center``."""
    f = [t - c for t, c in zip(target, center, strict=True)]
    n = math.sqrt(sum(v * v for v in f))
    z = [v / n for v in f]
    x = [z[1] * 1.0 - z[2] * 0.0, z[2] * 0.0 - z[0] * 1.0, 0.0]  # cross(z, up=(0,0,1))
    nx = math.hypot(x[0], x[1])
    x = [x[0] / nx, x[1] / nx, 0.0]
    y = [z[1] * x[2] - z[2] * x[1], z[2] * x[0] - z[0] * x[2], z[0] * x[1] - z[1] * x[0]]
    return [x, y, z]


def _project(r: list[list[float]], c: tuple[float, float, float], p: tuple[float, float, float]) -> tuple[float, ...]:
    d = [p[i] - c[i] for i in range(3)]
    xc = [sum(r[i][j] * d[j] for j in range(3)) for i in range(3)]
    if xc[2] <= 0.3:
        return ()
    return (DET_W_PX / 2 + DET_F_PX * xc[0] / xc[2], DET_H_PX / 2 + DET_F_PX * xc[1] / xc[2], xc[2])


def write_detection_cameras(
    out: Path, cams: list[Cam], walkers: list[Walker], fps: float, duration_s: float, room_m: float = 10.0
) -> dict[str, tuple[Path, Path]]:
    """Write a MOT detection file and a pinhole calibration per camera; return ``{id: (det, calib)}``.

    Each camera is a pinhole at ``cam``'s position and 2.5 m high, looking at the room's centre;
    a detection is the box a person detector would draw (feet to head, 0.5 m wide), with the
    person id as the track id. The files play a simulated detector, not ground truth to score.
    """
    files: dict[str, tuple[Path, Path]] = {}
    centre = (room_m / 2, room_m / 2, 0.9)
    for cam in cams:
        c = (cam.x_m, cam.y_m, 2.5)
        r = look_at(c, centre)
        t = [-sum(r[i][j] * c[j] for j in range(3)) for i in range(3)]
        d = out / cam.sensor_id
        d.mkdir(parents=True, exist_ok=True)
        calib = {
            "model": "pinhole",
            "image_size": [DET_W_PX, DET_H_PX],
            "K": [[DET_F_PX, 0.0, DET_W_PX / 2], [0.0, DET_F_PX, DET_H_PX / 2], [0.0, 0.0, 1.0]],
            "dist": [],
            "R": r,
            "t": t,
        }
        (d / "calibration.json").write_text(json.dumps(calib))
        lines = []
        for k in range(1, int(duration_s * fps) + 1):
            t_s = (k - 1) / fps
            for w in walkers:
                x, y = w.at(t_s)
                feet = _project(r, c, (x, y, 0.0))
                head = _project(r, c, (x, y, w.height_m))
                if not feet or not head:
                    continue
                width_px = DET_F_PX * 0.5 / feet[2]
                left, top, height = feet[0] - width_px / 2, head[1], feet[1] - head[1]
                if left < 0 or left + width_px > DET_W_PX or top < 0 or top + height > DET_H_PX or height <= 1:
                    continue
                lines.append(f"{k},{w.person_id},{left:.2f},{top:.2f},{width_px:.2f},{height:.2f},0.9,-1,-1,-1")
        (d / "det.txt").write_text("\n".join(lines) + "\n")
        files[cam.sensor_id] = (d / "det.txt", d / "calibration.json")
    return files


# ---------------------------------------------------------------------------
# The fleet: N sensor nodes in one process
# ---------------------------------------------------------------------------


@dataclass
class FleetStats:
    sent: int = 0
    late_sent: int = 0
    per_sensor: dict[str, int] = field(default_factory=dict)
    behind_ms_max: float = 0.0
    """Worst lateness of the publishing loop against the frame schedule."""


def sensor_info(cam: Cam, seq: int, fps: float, sigma_rad: float) -> SensorInfo:
    return SensorInfo(
        sensor_id=cam.sensor_id,
        seq=seq,
        stamp_ns=time.time_ns(),
        kind="panoramic",
        model=PanoramicModel(width_px=PANO_W_PX, height_px=PANO_H_PX, f_v_px=F_V_PX, v0_px=V0_PX),
        pose=Pose(x_m=cam.x_m, y_m=cam.y_m, z_m=cam.z_m, yaw_rad=cam.yaw_rad),
        pose_source="surveyed",
        fps=fps,
        bearing_sigma_rad=sigma_rad,
    )


def run_fleet(
    args: argparse.Namespace, world: tuple[list[Cam], list[Walker]] | None = None, max_range_m: float = MAX_RANGE_M
) -> FleetStats:
    """Publish ``args.sensors`` sensors at ``args.fps`` for ``args.duration`` s (forever if 0) or until SIGTERM.

    ``world``: the cameras and people to play (default: :func:`make_room`'s); ``max_range_m``: how far a camera
    sees people.

    Timing faults for the fault tests: ``--clock-offset-ms`` shifts every capture stamp (a node
    whose clock is off), ``--reorder`` holds back every k-th frame and sends it after the next
    one (out of order), ``--late-ms`` sends one frame in 30 that much late.
    """
    keys = Keys(args.prefix)
    cams, walkers = world or make_room(args.sensors, args.people, args.seed)
    if args.only:
        cams = [c for c in cams if c.sensor_id in set(args.only.split(","))]
    sigma = math.radians(0.2)
    rng = random.Random(args.seed + 1)
    stats = FleetStats(per_sensor={c.sensor_id: 0 for c in cams})
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    signal.signal(signal.SIGINT, lambda *_: stop.set())
    settings = SessionSettings(mode="client", connect=[args.connect])
    epoch_ns = args.epoch_ns or time.time_ns()
    with open_session(settings) as s:
        infos = {c.sensor_id: sensor_info(c, 0, args.fps, sigma) for c in cams}

        def on_info(q: Any) -> None:
            with q:
                for c in cams:
                    k = keys.sensor_info(c.sensor_id)
                    if q.key_expr.intersects(k):
                        q.reply(k, encode(infos[c.sensor_id]), encoding=MSGPACK)

        entities: list[Any] = [s.declare_queryable(keys.all_sensor_info, on_info)]
        entities += [s.liveliness().declare_token(keys.sensor(c.sensor_id)) for c in cams]
        pubs = {c.sensor_id: s.declare_publisher(keys.sensor_features(c.sensor_id), encoding=MSGPACK) for c in cams}
        for c in cams:
            s.put(keys.sensor_info(c.sensor_id), encode(infos[c.sensor_id]), encoding=MSGPACK)
        period_ns = int(1e9 / args.fps)
        start_ns = time.time_ns() + 200_000_000
        phase = {c.sensor_id: rng.randrange(period_ns) for c in cams}
        frame = dict.fromkeys(phase, 0)
        held: dict[str, bytes] = {}
        next_status_ns = start_ns
        seq_status = 0
        end_ns = start_ns + int(args.duration * 1e9) if args.duration > 0 else None
        while not stop.is_set():
            # The earliest due frame of any sensor.
            sid = min(frame, key=lambda k: frame[k] * period_ns + phase[k])
            due_ns = start_ns + frame[sid] * period_ns + phase[sid]
            if end_ns is not None and due_ns >= end_ns:
                break
            wait_s = (due_ns - time.time_ns()) / 1e9
            if wait_s > 0 and stop.wait(wait_s):
                break
            now_ns = time.time_ns()
            stats.behind_ms_max = max(stats.behind_ms_max, (now_ns - due_ns) / 1e6)
            cam = next(c for c in cams if c.sensor_id == sid)
            t_world_s = (due_ns - epoch_ns) / 1e9
            k = frame[sid]
            msg = Features(
                sensor_id=sid,
                seq=k,
                stamp_ns=due_ns + int(args.clock_offset_ms * 1e6),
                frame_index=k,
                blobs=observe(cam, walkers, t_world_s, rng, sigma, max_range_m),
                processing_ms=(now_ns - due_ns) / 1e6,
            )
            data = encode(msg)
            frame[sid] += 1
            if args.reorder and k % args.reorder == 1:
                held[sid] = data  # sent after the next frame: out of order
            elif args.late_ms and k % 30 == 15:
                threading.Timer(args.late_ms / 1e3, pubs[sid].put, (data,)).start()
                stats.late_sent += 1
            else:
                pubs[sid].put(data)
                if sid in held:
                    pubs[sid].put(held.pop(sid))
            stats.sent += 1
            stats.per_sensor[sid] += 1
            if now_ns >= next_status_ns:
                next_status_ns += 1_000_000_000
                seq_status += 1
                for c in cams:
                    st = NodeStatus(
                        sensor_id=c.sensor_id,
                        seq=seq_status,
                        stamp_ns=now_ns,
                        fps=args.fps,
                        frames=frame[c.sensor_id],
                        dropped_frames=0,
                        processing_ms=0.1,
                        clock_offset_ns=0,
                        clock_uncertainty_ns=0,
                        clock_source="system",
                        decode_errors=0,
                        source_state="ok",
                    )
                    s.put(keys.sensor_status(c.sensor_id), encode(st), encoding=MSGPACK)
                    if seq_status % 5 == 0:  # re-announce info now and then, as a node does on change
                        s.put(keys.sensor_info(c.sensor_id), encode(infos[c.sensor_id]), encoding=MSGPACK)
        for p in pubs.values():
            p.undeclare()
        for e in entities:
            e.undeclare()
    return stats


# ---------------------------------------------------------------------------
# The benchmark driver
# ---------------------------------------------------------------------------


def _free_port() -> int:
    import socket

    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def _rss_kib(pid: int) -> int | None:
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    except OSError:
        return None
    return None


def _wait_port(port: int, timeout_s: float) -> None:
    import socket

    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            with socket.create_connection(("127.0.0.1", port), timeout=0.2):
                return
        except OSError:
            time.sleep(0.05)
    raise SystemExit(f"bench_load: router on port {port} did not come up within {timeout_s} s")


def manager_config(
    path: Path, prefix: str, endpoint: str, rate_hz: float, state_dir: Path, sensors: list[str], schedule: str
) -> float:
    """Write the manager's config (it fuses ``sensors`` by ``schedule``); return its ``latency_ms`` (the default:
    the most a late sensor is waited for, or the fixed mode's delay)."""
    latency_ms = 200.0
    listed = ", ".join(f'"{sid}"' for sid in sensors)
    path.write_text(
        "[manager]\n"
        'id = "bench"\n'
        f'prefix = "{prefix}"\n'
        f"rate_hz = {rate_hz}\n"
        f'schedule = "{schedule}"\n'
        f"latency_ms = {latency_ms}\n"
        f'state_dir = "{state_dir}"\n'
        f"sensors = [{listed}]\n"
        "[zenoh]\n"
        'mode = "client"\n'
        f'connect = ["{endpoint}"]\n'
    )
    return latency_ms


def _percentiles(xs: list[float]) -> dict[str, float | None]:
    if not xs:
        return {"p50": None, "p90": None, "p99": None, "max": None, "n": 0}
    q = statistics.quantiles(xs, n=100, method="inclusive") if len(xs) > 1 else [xs[0]] * 99
    return {
        "p50": round(q[49], 2),
        "p90": round(q[89], 2),
        "p99": round(q[98], 2),
        "max": round(max(xs), 2),
        "n": len(xs),
    }


def run_bench(args: argparse.Namespace, schedule: str) -> dict[str, Any]:
    prefix = "bench"
    keys = Keys(prefix)
    tmp = Path(tempfile.mkdtemp(prefix="bench-load-"))
    port = _free_port()
    endpoint = f"tcp/127.0.0.1:{port}"
    env = dict(os.environ, PYTHONUNBUFFERED="1", PYTHONPATH=str(REPO))
    procs: list[subprocess.Popen[bytes]] = []

    def start(name: str, argv: list[str]) -> subprocess.Popen[bytes]:
        with (tmp / f"{name}.log").open("wb") as log:
            p = subprocess.Popen(argv, stdout=log, stderr=subprocess.STDOUT, env=env, cwd=REPO)
        procs.append(p)
        return p

    py = sys.executable
    arrivals: list[tuple[int, int, int, int, int]] = []  # (arrival_ns, stamp_ns, seq, n_tracks, published_ns)
    errors_m: list[float] = []
    """Distance of each confirmed track state to the nearest simulated person (scoring only)."""
    epoch_ns = time.time_ns()
    _, walkers = make_room(args.sensors, args.people, args.seed)
    statuses: list[ManagerStatus] = []
    lock = threading.Lock()
    rss: list[tuple[float, int]] = []
    try:
        start("router", [py, "-m", "panostereo", "router", "--listen", endpoint])
        _wait_port(port, 20.0)
        mgr_cfg = tmp / "manager.toml"
        cams, _ = make_room(args.sensors, args.people, args.seed)
        wait_ms = manager_config(
            mgr_cfg, prefix, endpoint, args.rate_hz, tmp / "state", [c.sensor_id for c in cams], schedule
        )
        mgr = start("manager", [py, "-m", "panostereo", "manager", "--config", str(mgr_cfg), "--log-level", "WARNING"])
        with open_session(SessionSettings(mode="client", connect=[endpoint])) as s:

            def on_tracks(sample: Any) -> None:
                now = time.time_ns()
                ts = decode(sample.payload.to_bytes(), TrackSet)
                t_s = (ts.stamp_ns - epoch_ns) / 1e9
                errs = [
                    min(math.hypot(t.x_m - x, t.y_m - y) for x, y in (w.at(t_s) for w in walkers))
                    for t in ts.tracks
                    if t.state == "confirmed"
                ]
                with lock:
                    arrivals.append((now, ts.stamp_ns, ts.seq, len(ts.tracks), ts.published_ns))
                    errors_m.extend(errs)

            def on_status(sample: Any) -> None:
                with lock:
                    statuses.append(decode(sample.payload.to_bytes(), ManagerStatus))

            subs = [
                s.declare_subscriber(keys.tracks(), on_tracks),
                s.declare_subscriber(keys.all_manager_status, on_status),
            ]
            deadline = time.monotonic() + 30
            while not statuses and time.monotonic() < deadline:
                if mgr.poll() is not None:
                    raise SystemExit(
                        f"bench_load: manager exited with {mgr.returncode}:\n{(tmp / 'manager.log').read_text()}"
                    )
                time.sleep(0.1)
            if not statuses:
                raise SystemExit(f"bench_load: no ManagerStatus within 30 s:\n{(tmp / 'manager.log').read_text()}")
            fleet_out = tmp / "fleet.json"
            node_frames: dict[str, int] = {}

            def on_node_status(sample: Any) -> None:
                st = decode(sample.payload.to_bytes(), NodeStatus)
                with lock:
                    node_frames[st.sensor_id] = st.frames

            subs.append(s.declare_subscriber(keys.all_sensor_status, on_node_status))
            if args.nodes == "real":
                # One real `panostereo node` process per camera, each playing its detection file.
                cams, _ = make_room(args.sensors, args.people, args.seed)
                epoch_ns = time.time_ns() + int(args.startup_s * 1e9)
                files = write_detection_cameras(tmp / "cams", cams, walkers, args.fps, args.duration + 5)
                runners = []
                for cam in cams:
                    det, calib = files[cam.sensor_id]
                    cfg = tmp / f"node-{cam.sensor_id}.toml"
                    cfg.write_text(
                        f'[node]\nid = "{cam.sensor_id}"\nprefix = "{prefix}"\n[zenoh]\nconnect = ["{endpoint}"]\n'
                        f'[source]\nkind = "detections"\nfile = "{det}"\ncalibration = "{calib}"\n'
                        f"fps = {args.fps}\nepoch_ns = {epoch_ns}\n"
                    )
                    runners.append(
                        start(f"node-{cam.sensor_id}", [py, "-m", "panostereo", "node", "--config", str(cfg)])
                    )
                end_s = time.monotonic() + args.startup_s + args.duration
            else:
                runners = [
                    start(
                        "fleet",
                        [
                            py,
                            "-m",
                            "benchmarks.bench_load",
                            "fleet",
                            "--connect",
                            endpoint,
                            "--prefix",
                            prefix,
                            "--sensors",
                            str(args.sensors),
                            "--fps",
                            str(args.fps),
                            "--people",
                            str(args.people),
                            "--duration",
                            str(args.duration),
                            "--seed",
                            str(args.seed),
                            "--stats",
                            str(fleet_out),
                            "--epoch-ns",
                            str(epoch_ns),
                        ],
                    )
                ]
                end_s = time.monotonic() + args.duration + 60
            t0 = time.monotonic()
            while any(r.poll() is None for r in runners) and time.monotonic() < end_s:
                r_kib = _rss_kib(mgr.pid)
                if r_kib is not None:
                    rss.append((time.monotonic() - t0, r_kib))
                time.sleep(1.0)
            for r in runners:
                if r.poll() is None:
                    r.send_signal(signal.SIGTERM)
                r.wait(timeout=30)
            time.sleep(1.5)  # the last ticks and a status after the cameras stopped
            for sub in subs:
                sub.undeclare()
        fleet_stats = json.loads(fleet_out.read_text()) if fleet_out.exists() else {}
        if args.nodes == "real":
            fleet_stats = {"sent": sum(node_frames.values())}
            args.warmup = max(args.warmup, args.startup_s + 2)
        warm_s = args.warmup
        with lock:
            live = list(arrivals)
        t_first = min((a for a, *_ in live), default=0)
        warm = [x for x in live if (x[0] - t_first) / 1e9 >= warm_s] or live
        lat = [(a - st) / 1e6 for a, st, *_ in warm]
        to_agent = [(a - pub) / 1e6 for a, _, _, _, pub in warm if pub]
        seqs = sorted({sq for _, _, sq, _, _ in live})
        gaps = sum(b - a - 1 for a, b in itertools.pairwise(seqs) if b > a + 1)
        last = statuses[-1] if statuses else None
        t_status0 = statuses[0].stamp_ns if statuses else 0
        warm_status = [st for st in statuses if (st.stamp_ns - t_status0) / 1e9 >= warm_s and st.latency]
        rss_warm = [r for t, r in rss if t >= warm_s]
        duration_ticks = (max((a for a, *_ in live), default=0) - t_first) / 1e9
        sent = fleet_stats.get("sent")
        received = last.frames_received if last else None
        missed: dict[str, int] = {}
        for st in statuses:
            for t in st.timing:
                missed[t.sensor_id] = max(missed.get(t.sensor_id, 0), t.missed)
        ticking = [st for st in warm_status if st.tick_rate_hz > 0]

        def part(name: str) -> float | None:
            xs = [getattr(st.latency, name) for st in warm_status]
            return round(statistics.median(xs), 2) if xs else None

        return {
            "schedule": schedule,
            "alignment_max_wait_ms": wait_ms,
            "frames_sent": sent,
            "frames_received": received,
            "frames_lost": sent - received if sent is not None and received is not None else None,
            "fleet_behind_ms_max": fleet_stats.get("behind_ms_max"),
            "tracksets_received": len(live),
            "tracksets_lost": gaps,
            "tick_rate_hz_achieved": round(len(live) / duration_ticks, 2) if duration_ticks > 0 else None,
            "tracks_mean": round(statistics.fmean(x[3] for x in live), 2) if live else 0,
            "manager_dropped_msgs": last.dropped_msgs if last else None,
            "manager_late_msgs": last.late_msgs if last else None,
            "manager_decode_errors": last.decode_errors if last else None,
            "manager_out_of_order_msgs": last.out_of_order_msgs if last else None,
            "manager_missed_deadlines": sum(missed.values()),
            "manager_sensors_in_use_max": max((len(st.sensors_in_use) for st in statuses), default=0),
            "track_error_m": {
                "p50": round(statistics.median(errors_m), 3) if errors_m else None,
                "p90": round(statistics.quantiles(errors_m, n=10)[8], 3) if len(errors_m) > 1 else None,
                "p99": round(statistics.quantiles(errors_m, n=100)[98], 3) if len(errors_m) > 1 else None,
                "share_within_0_5m": round(sum(e < 0.5 for e in errors_m) / len(errors_m), 4) if errors_m else None,
                "n": len(errors_m),
            },
            "manager_tick_ms": round(statistics.median(st.tick_ms for st in ticking), 2) if ticking else None,
            "manager_tick_p99_ms": round(max(st.tick_p99_ms for st in ticking), 2) if ticking else None,
            "latency_ms": _percentiles(lat),
            "latency_breakdown_ms": {
                "node": part("node_ms"),
                "transport": part("transport_ms"),
                "watermark_wait": part("wait_ms"),
                "fusion": part("fusion_ms"),
                "publish": part("publish_ms"),
                "to_agent": round(statistics.median(to_agent), 2) if to_agent else None,
                "capture_to_publish_p50": part("age_p50_ms"),
            },
            "manager_rss_mib": {
                "first_after_warmup": round(rss_warm[0] / 1024, 1) if rss_warm else None,
                "last": round(rss_warm[-1] / 1024, 1) if rss_warm else None,
                "max": round(max(rss_warm) / 1024, 1) if rss_warm else None,
                "growth": round((rss_warm[-1] - rss_warm[0]) / 1024, 1) if rss_warm else None,
            },
            "logs": str(tmp),
        }
    finally:
        stop_processes(procs)


def stop_processes(procs: list[subprocess.Popen[bytes]]) -> None:
    """Stop the processes still running, the last started first: SIGTERM, then SIGKILL after 10 s."""
    for p in reversed(procs):
        if p.poll() is None:
            p.send_signal(signal.SIGTERM)
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="bench_load", description=__doc__.split("\n\n")[0])
    sub = p.add_subparsers(dest="cmd")
    f = sub.add_parser("fleet", help="run only the simulated sensors (used by the benchmark and the tests)")
    for q in (p, f):
        q.add_argument("--sensors", type=int, default=16)
        q.add_argument("--fps", type=float, default=30.0)
        q.add_argument("--people", type=int, default=6)
        q.add_argument("--duration", type=float, default=60.0, help="seconds (fleet: 0 = until SIGTERM)")
        q.add_argument("--seed", type=int, default=1)
    p.add_argument("--rate-hz", type=float, default=10.0, help="manager's most fusions per second")
    p.add_argument(
        "--schedules",
        default="watermark,fixed",
        help="the manager schedules to run, one after the other (watermark: event-driven; fixed: the old wait)",
    )
    p.add_argument(
        "--nodes",
        choices=["fleet", "real"],
        default="fleet",
        help="fleet: one process plays every camera; real: one `panostereo node` process per camera",
    )
    p.add_argument("--startup-s", type=float, default=10.0, help="real nodes: time allowed for them to start")
    p.add_argument("--warmup", type=float, default=5.0, help="seconds left out of latency and memory figures")
    p.add_argument("--out", type=Path, default=None, help="also write the JSON here")
    f.add_argument("--connect", required=True)
    f.add_argument("--prefix", default="pano")
    f.add_argument("--only", default="", help="comma-separated sensor ids to play (default all)")
    f.add_argument("--epoch-ns", type=int, default=0, help="world time origin (0: now)")
    f.add_argument("--clock-offset-ms", type=float, default=0.0, help="add this to every capture stamp")
    f.add_argument("--reorder", type=int, default=0, help="send every k-th frame after the next one (0: never)")
    f.add_argument("--late-ms", type=float, default=0.0, help="send one frame in 30 this much late (0: never)")
    f.add_argument("--stats", type=Path, default=None, help="write the fleet's counters here as JSON at exit")
    args = p.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, stream=sys.stderr)
    if args.cmd == "fleet":
        stats = run_fleet(args)
        if args.stats:
            args.stats.write_text(json.dumps(stats.__dict__))
        return 0
    runs = {mode: run_bench(args, mode) for mode in args.schedules.split(",")}
    result: dict[str, Any] = {
        "benchmark": "bench_load",
        "cameras": "one panostereo node process per camera (detection files)"
        if args.nodes == "real"
        else "one fleet process playing every camera",
        "sensors": args.sensors,
        "fps": args.fps,
        "people": args.people,
        "duration_s": args.duration,
        "manager_max_rate_hz": args.rate_hz,
        "runs": runs,
    }
    w = runs.get("watermark")
    if w is not None:
        lat = w["latency_ms"]
        result["targets"] = {
            "latency_p50_le_50ms": lat["p50"] is not None and lat["p50"] <= 50.0,
            "latency_p99_le_100ms": lat["p99"] is not None and lat["p99"] <= 100.0,
            "zero_frames_lost": w["frames_lost"] == 0 and w["manager_dropped_msgs"] == 0,
            "memory_growth_mib": w["manager_rss_mib"]["growth"],
        }
        f = runs.get("fixed")
        if f is not None:
            result["targets"]["accuracy_within_0_5m_vs_fixed"] = [
                w["track_error_m"]["share_within_0_5m"],
                f["track_error_m"]["share_within_0_5m"],
            ]
    text = json.dumps(result, indent=2)
    if args.out:
        args.out.write_text(text + "\n")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
