"""Faults (issue 8): killed nodes, a killed manager under ``panostereo up``, a restarted router,
a partitioned camera host, a node whose clock is 2 s off, late and out-of-order frames.

Every test runs real processes on loopback: a ``panostereo router``, a ``panostereo manager`` and
real ``panostereo node`` processes whose source is a detection file (a simulated person detector
on pinhole cameras: the node process, its session, liveliness, info and publication are the real
ones, without the cost of rendering pixels). The frames of the simulated room come from
``benchmarks.bench_load`` (people walking back and forth, cameras around the room). The test
itself is a user agent: it subscribes to TrackSets and the manager's status.
"""

from __future__ import annotations

import contextlib
import os
import re
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest

from benchmarks.bench_load import Cam, Walker, make_room, write_detection_cameras
from common.codec import decode
from common.keys import Keys
from common.schema import ManagerStatus, NodeStatus, Track, TrackSet
from common.session import SessionSettings, open_session
from tests.support import (
    FakeNtpServer,
    ManagedProcess,
    free_port,
    router_command,
    skip_or_fail,
    spawn,
    wait_for,
    wait_for_port,
)

pytestmark = [pytest.mark.integration, pytest.mark.timeout(150)]

FPS = 10.0
LOOP_S = 120.0
"""Length of the detection files; nodes loop over them."""
SENSORS = 4
PEOPLE = 3
SEED = 5
MANAGER_ID = "mgr1"
READY_S = 45.0
"""Deadline for a whole site to come up and produce confirmed tracks (loaded 2-core CI)."""


# ---------------------------------------------------------------------------
# The site under test
# ---------------------------------------------------------------------------


@dataclass
class Observer:
    """The test's user agent: TrackSets, manager status and sensor liveliness, with arrival times."""

    keys: Keys
    sets: list[tuple[float, TrackSet]] = field(default_factory=list)
    status: list[tuple[float, ManagerStatus]] = field(default_factory=list)
    alive_events: list[tuple[float, str, bool]] = field(default_factory=list)
    lock: threading.Lock = field(default_factory=threading.Lock)

    def attach(self, session: Any) -> list[Any]:
        def on_set(sample: Any) -> None:
            msg = decode(sample.payload.to_bytes(), TrackSet)
            with self.lock:
                self.sets.append((time.monotonic(), msg))

        def on_status(sample: Any) -> None:
            msg = decode(sample.payload.to_bytes(), ManagerStatus)
            with self.lock:
                self.status.append((time.monotonic(), msg))

        def on_alive(sample: Any) -> None:
            import zenoh

            with self.lock:
                self.alive_events.append((time.monotonic(), str(sample.key_expr), sample.kind == zenoh.SampleKind.PUT))

        return [
            session.declare_subscriber(self.keys.tracks(), on_set),
            session.declare_subscriber(self.keys.all_manager_status, on_status),
            session.liveliness().declare_subscriber(self.keys.all_sensors, on_alive, history=True),
            session.liveliness().declare_subscriber(self.keys.all_managers, on_alive, history=True),
        ]

    def sets_since(self, t: float) -> list[TrackSet]:
        with self.lock:
            return [m for a, m in self.sets if a >= t]

    def status_since(self, t: float) -> list[ManagerStatus]:
        with self.lock:
            return [m for a, m in self.status if a >= t]

    def confirmed(self, ts: TrackSet) -> list[Track]:
        return [t for t in ts.tracks if t.state == "confirmed"]

    def tracking_with(self, since: float, need: set[str], min_sets: int = 5) -> bool:
        """At least ``min_sets`` TrackSets since ``since`` with confirmed tracks, all of ``need`` in use."""
        good = [s for s in self.sets_since(since) if self.confirmed(s) and need <= set(s.sensors_used)]
        return len(good) >= min_sets

    def alive_change(self, key: str, alive: bool, since: float) -> float | None:
        """Arrival time of the first liveliness change of ``key`` to ``alive`` after ``since``."""
        with self.lock:
            for a, k, up in self.alive_events:
                if a >= since and k == key and up == alive:
                    return a
        return None


@dataclass
class FaultSite:
    """Configs and processes of one small site: router, manager, one detection node per camera."""

    tmp: Path
    prefix: str
    port: int
    epoch_ns: int
    cams: list[Cam]
    walkers: list[Walker]
    files: dict[str, tuple[Path, Path]]
    log_dir: Path
    procs: list[ManagedProcess] = field(default_factory=list)
    connect_to: str = ""
    """Endpoint the site's processes connect to, if not ``tcp/127.0.0.1:{port}`` (e.g. a TLS one)."""

    @property
    def keys(self) -> Keys:
        return Keys(self.prefix)

    @property
    def endpoint(self) -> str:
        return self.connect_to or f"tcp/127.0.0.1:{self.port}"

    @property
    def ids(self) -> list[str]:
        return [c.sensor_id for c in self.cams]

    def _spawn(self, args: list[str], name: str, env: dict[str, str] | None = None) -> ManagedProcess:
        p = spawn(args, env=env, log_dir=self.log_dir, name=name)
        self.procs.append(p)
        return p

    def start_router(self, *extra_listen: str) -> ManagedProcess:
        listen = [a for ep in extra_listen for a in ("--listen", ep)]
        p = self._spawn([*router_command(self.port), *listen], f"router-{self.port}")
        wait_for_port(self.port, 20.0, proc=p)
        return p

    def node_config(
        self, sid: str, *, connect: str | None = None, ntp_port: int | None = None, lease_ms: int = 3000
    ) -> Path:
        det, calib = self.files[sid]
        clock = f'ntp_server = "127.0.0.1"\nntp_port = {ntp_port}\nresync_s = 2.0\n' if ntp_port else ""
        path = self.tmp / f"node-{sid}{'-ntp' if ntp_port else ''}.toml"
        path.write_text(
            f'[node]\nid = "{sid}"\nprefix = "{self.prefix}"\n'
            f'[zenoh]\nconnect = ["{connect or self.endpoint}"]\nconnect_timeout_ms = 20000\nlease_ms = {lease_ms}\n'
            f"[clock]\n{clock}"
            f'[source]\nkind = "detections"\nfile = "{det}"\ncalibration = "{calib}"\n'
            f"fps = {FPS}\nepoch_ns = {self.epoch_ns}\nloop = true\nmax_lag_s = 5.0\n"
        )
        return path

    def manager_config(
        self, *, ntp_port: int | None = None, state_dir: Path | None = None, extra_sensors: tuple[str, ...] = ()
    ) -> Path:
        """The manager fuses the site's cameras (and ``extra_sensors``); any other sensor id is refused."""
        clock = f'ntp_server = "127.0.0.1"\nntp_port = {ntp_port}\nresync_s = 2.0\n' if ntp_port else ""
        path = self.tmp / "manager.toml"
        sensors = ", ".join(f'"{sid}"' for sid in [*self.ids, *extra_sensors])
        path.write_text(
            f'[manager]\nid = "{MANAGER_ID}"\nprefix = "{self.prefix}"\nrate_hz = 10.0\n'
            f'state_dir = "{state_dir or self.tmp / "state"}"\nsensors = [{sensors}]\n'
            f'[zenoh]\nconnect = ["{self.endpoint}"]\nconnect_timeout_ms = 20000\n'
            f"[clock]\n{clock}"
        )
        return path

    def start_node(
        self, sid: str, config: Path | None = None, netns: str | None = None, extra: tuple[str, ...] = ()
    ) -> ManagedProcess:
        args = [sys.executable, "-m", "panostereo", "node", "--config", str(config or self.node_config(sid)), *extra]
        if netns:
            args = ["ip", "netns", "exec", netns, *args]
        return self._spawn(args, f"node-{sid}")

    def start_manager(self, config: Path | None = None, extra: tuple[str, ...] = ()) -> ManagedProcess:
        cfg = config or self.manager_config()
        return self._spawn([sys.executable, "-m", "panostereo", "manager", "--config", str(cfg), *extra], "manager")

    def zoned_site_file(
        self, name: str, zones: dict[str, tuple[float, float]], reach_m: float, band_m: float | None = None
    ) -> Path:
        """A site file of this room's cameras and nodes, cut into ``zones`` (name -> its x span, the room's whole
        depth), each zone's cameras those within ``reach_m`` of it."""
        band = f"zone_band_m = {band_m}\n" if band_m is not None else ""
        text = f'[site]\nname = "{name}"\nprefix = "{self.prefix}"\nrouter = "{self.endpoint}"\n{band}'
        for cam in self.cams:
            sid = cam.sensor_id
            text += f'[[camera]]\nid = "{sid}"\nx_m = {cam.x_m}\ny_m = {cam.y_m}\n'
            text += f'[[process]]\nname = "{sid}"\ncommand = "node"\nconfig = "{self.node_config(sid)}"\n'
        for zone, (x0, x1) in zones.items():
            polygon = f"[[{x0}, 0], [{x1}, 0], [{x1}, 10], [{x0}, 10]]"
            text += f'[[zones]]\nname = "{zone}"\npolygon = {polygon}\nreach_m = {reach_m}\n'
        path = self.tmp / "site.toml"
        path.write_text(text)
        return path

    def stop_all(self) -> None:
        for p in reversed(self.procs):
            p.stop()

    def logs(self) -> str:
        return "".join(p.log() for p in self.procs)


def make_fault_site(
    tmp_path: Path, prefix: str = "faults", room: tuple[list[Cam], list[Walker]] | None = None
) -> FaultSite:
    """The room (default: :func:`make_room`'s), its detection files and an unused router port (nothing started
    yet)."""
    cams, walkers = room if room is not None else make_room(SENSORS, PEOPLE, SEED)
    files = write_detection_cameras(tmp_path / "cams", cams, walkers, FPS, LOOP_S)
    return FaultSite(
        tmp=tmp_path,
        prefix=prefix,
        port=free_port(),
        epoch_ns=time.time_ns(),
        cams=cams,
        walkers=walkers,
        files=files,
        log_dir=tmp_path / "logs",
    )


@contextlib.contextmanager
def running(s: FaultSite, request: pytest.FixtureRequest) -> Iterator[FaultSite]:
    """Stop every process of the site at the end; print their logs if the test failed."""
    try:
        yield s
    finally:
        s.stop_all()
        rep = getattr(request.node, "rep_call", None)
        if rep is not None and rep.failed:
            sys.stderr.write(s.logs())


@pytest.fixture
def site(tmp_path: Path, request: pytest.FixtureRequest) -> Iterator[FaultSite]:
    with running(make_fault_site(tmp_path), request) as s:
        yield s


@contextlib.contextmanager
def observing_session(session: Any, site: FaultSite) -> Iterator[Observer]:
    """An Observer on an already open session, its subscribers undeclared at the end."""
    obs = Observer(site.keys)
    entities = obs.attach(session)
    try:
        yield obs
    finally:
        for e in entities:
            with contextlib.suppress(Exception):
                e.undeclare()


@contextlib.contextmanager
def observing(site: FaultSite) -> Iterator[Observer]:
    settings = SessionSettings(mode="client", connect=[site.endpoint], connect_timeout_ms=20_000)
    with open_session(settings) as session, observing_session(session, site) as obs:
        yield obs


def _up_to_speed(site: FaultSite, obs: Observer, need: set[str] | None = None, timeout_s: float = READY_S) -> None:
    """Wait until the manager tracks people with every camera of ``need`` in use."""
    want = set(site.ids) if need is None else need
    t0 = time.monotonic()
    wait_for(lambda: obs.tracking_with(t0, want), timeout_s, f"confirmed tracks using {sorted(want)}", poll_s=0.1)


def start_tracking(site: FaultSite, obs: Observer) -> dict[str, ManagedProcess]:
    """The site's manager and every sensor node started, once the manager tracks with every camera: the nodes by
    id."""
    site.start_manager()
    nodes = {sid: site.start_node(sid) for sid in site.ids}
    _up_to_speed(site, obs)
    return nodes


# ---------------------------------------------------------------------------
# kill -9 a sensor node
# ---------------------------------------------------------------------------


def test_kill9_sensor_node_tracking_continues_and_it_rejoins(site: FaultSite) -> None:
    site.start_router()
    with observing(site) as obs:
        nodes = start_tracking(site, obs)
        victim = site.ids[1]
        rest = set(site.ids) - {victim}
        t_kill = time.monotonic()
        nodes[victim].signal(signal.SIGKILL)
        nodes[victim].wait(5.0)
        # Presence goes at once (the OS closes the socket), and the manager stops using the camera.
        wait_for(lambda: obs.alive_change(site.keys.sensor(victim), False, t_kill), 5.0, f"{victim}'s token to go")
        wait_for(
            lambda: any(
                victim not in s.sensors_in_use and victim in s.sensors_absent for s in obs.status_since(t_kill + 0.5)
            ),
            10.0,
            f"the manager's status to mark {victim} absent",
        )
        t_gone = time.monotonic()
        # Tracking continues on the remaining cameras, and nothing claims the dead camera.
        wait_for(lambda: obs.tracking_with(t_gone, rest, min_sets=10), 15.0, "tracks from the remaining cameras")
        assert not [s for s in obs.sets_since(t_gone) if victim in s.sensors_used]
        # It rejoins: token within 3 s of the restart, back in use soon after.
        t_restart = time.monotonic()
        site.start_node(victim)
        t_token = wait_for(
            lambda: obs.alive_change(site.keys.sensor(victim), True, t_restart), 10.0, f"{victim}'s token again"
        )
        wait_for(lambda: obs.tracking_with(t_restart, {victim}, min_sets=3), 15.0, f"{victim} in use again")
        t_back = time.monotonic()
        wait_for(
            lambda: any(victim not in s.sensors_absent for s in obs.status_since(t_back)),
            5.0,
            f"the manager's status to stop marking {victim} absent",
        )
        rejoin_s = t_token - t_restart
        assert rejoin_s <= 3.0, f"{victim} announced itself {rejoin_s:.2f} s after its restart (goal: within 3 s)"
    for p in site.procs:
        if p is not nodes[victim]:
            assert p.alive, p.log()


# ---------------------------------------------------------------------------
# restart the router
# ---------------------------------------------------------------------------


def test_router_restart_clients_reconnect_and_data_flows(site: FaultSite) -> None:
    router = site.start_router()
    with observing(site) as obs:
        start_tracking(site, obs)
        router.signal(signal.SIGKILL)
        router.wait(5.0)
        t_down = time.monotonic()
        wait_for(lambda: not obs.sets_since(t_down + 0.5), 5.0, "TrackSets to stop while the router is down")
        site.start_router()
        t_up = time.monotonic()
        # Every client (the nodes, the manager, this agent) reconnects by itself; data flows end to end.
        _up_to_speed(site, obs, timeout_s=30.0)
        t_ok = time.monotonic()
        assert t_ok - t_up < 30.0
    for p in site.procs:
        if p is not router:
            assert p.alive, f"{p.name} died when the router restarted:\n{p.log()}"


# ---------------------------------------------------------------------------
# partition one camera host (network namespace + veth pair)
# ---------------------------------------------------------------------------


def _ip(*args: str) -> None:
    res = subprocess.run(["ip", *args], capture_output=True, text=True, timeout=10, check=False)
    if res.returncode != 0:
        raise AssertionError(f"ip {' '.join(args)} failed: {res.stderr.strip()}")


@dataclass
class CameraHost:
    """A network namespace joined to this host by a veth pair: 10.213.N.1 (here) <-> 10.213.N.2 (there)."""

    ns: str
    veth_here: str
    here_ip: str

    def cut(self) -> None:
        _ip("link", "set", "dev", self.veth_here, "down")

    def heal(self) -> None:
        _ip("link", "set", "dev", self.veth_here, "up")


@contextlib.contextmanager
def camera_host() -> Iterator[CameraHost]:
    if os.geteuid() != 0:
        skip_or_fail("network namespaces and veth pairs need root (CI runs as root)")
    tag = f"{os.getpid() % 100000}"
    net = 1 + os.getpid() % 250
    ns, here, there = f"psns{tag}", f"psh{tag}", f"psc{tag}"
    here_ip, there_ip = f"10.213.{net}.1", f"10.213.{net}.2"
    try:
        _ip("netns", "add", ns)
        _ip("link", "add", here, "type", "veth", "peer", "name", there)
        _ip("link", "set", there, "netns", ns)
        _ip("addr", "add", f"{here_ip}/30", "dev", here)
        _ip("link", "set", "dev", here, "up")
        _ip("-n", ns, "addr", "add", f"{there_ip}/30", "dev", there)
        _ip("-n", ns, "link", "set", "dev", there, "up")
        _ip("-n", ns, "link", "set", "dev", "lo", "up")
        yield CameraHost(ns, here, here_ip)
    finally:
        subprocess.run(["ip", "link", "del", here], capture_output=True, timeout=10, check=False)
        subprocess.run(["ip", "netns", "del", ns], capture_output=True, timeout=10, check=False)


def test_partitioned_camera_host_no_stale_tracks_and_recovery(site: FaultSite) -> None:
    with camera_host() as host:
        site.start_router(f"tcp/{host.here_ip}:{site.port}")
        with observing(site) as obs:
            site.start_manager()
            cut_id = site.ids[2]
            for sid in site.ids:
                if sid == cut_id:
                    cfg = site.node_config(sid, connect=f"tcp/{host.here_ip}:{site.port}", lease_ms=2000)
                    site.start_node(sid, cfg, netns=host.ns)
                else:
                    site.start_node(sid)
            _up_to_speed(site, obs)
            host.cut()
            t_cut = time.monotonic()
            # The router notices when the node's lease (2 s) runs out; the manager drops the camera.
            wait_for(lambda: obs.alive_change(site.keys.sensor(cut_id), False, t_cut), 10.0, "the cut node's token")
            wait_for(
                lambda: any(cut_id not in s.sensors_in_use for s in obs.status_since(t_cut + 0.5)),
                10.0,
                "the manager to leave the cut camera out",
            )
            t_out = time.monotonic()
            rest = set(site.ids) - {cut_id}
            wait_for(lambda: obs.tracking_with(t_out, rest, min_sets=10), 15.0, "tracking on the connected cameras")
            # No stale tracks while cut off: no TrackSet uses the cut camera, no track is localised by it.
            stale = [s for s in obs.sets_since(t_out) if cut_id in s.sensors_used]
            stale += [s for s in obs.sets_since(t_out) if any(cut_id in t.sensors for t in s.tracks)]
            assert not stale, stale[:2]
            host.heal()
            t_heal = time.monotonic()
            wait_for(lambda: obs.alive_change(site.keys.sensor(cut_id), True, t_heal), 20.0, "the node's token back")
            wait_for(lambda: obs.tracking_with(t_heal, set(site.ids), min_sets=3), 20.0, "the healed camera in use")


# ---------------------------------------------------------------------------
# one node's clock 2 s off, corrected through NTP
# ---------------------------------------------------------------------------


def test_node_clock_two_seconds_off_is_corrected_by_ntp(site: FaultSite) -> None:
    """Everyone's reference (the NTP server) is 2 s ahead of this host's clock.

    The manager and three nodes synchronise to it. The fourth node first runs on its system
    clock, 2 s behind everyone: its frames are further from the manager's clock than
    ``max_skew_s`` (1.5 s), refused and counted as clock skew against it, and it is never used.
    Restarted with the same NTP server it is corrected and used.
    """
    with FakeNtpServer(skew_s=2.0) as ntp:
        site.start_router()
        with observing(site) as obs:
            site.start_manager(site.manager_config(ntp_port=ntp.port))
            off = site.ids[3]
            rest = set(site.ids) - {off}
            for sid in sorted(rest):
                site.start_node(sid, site.node_config(sid, ntp_port=ntp.port))
            skewed = site.start_node(off, site.node_config(off))
            _up_to_speed(site, obs, need=rest)
            t0 = time.monotonic()
            wait_for(lambda: len(obs.status_since(t0)) >= 3, 10.0, "three manager status messages")
            assert not [s for s in obs.sets_since(t0) if off in s.sensors_used], "frames 2 s old were fused"
            counted = [next((r.skewed for r in s.refused if r.sender_id == off), 0) for s in obs.status_since(t0)]
            assert counted[-1] > counted[0], f"the manager does not count {off}'s 2 s old frames as skewed: {counted}"
            skewed.stop()
            t1 = time.monotonic()
            site.start_node(off, site.node_config(off, ntp_port=ntp.port))
            wait_for(lambda: obs.tracking_with(t1, set(site.ids), min_sets=5), 30.0, f"{off} in use once corrected")
            # The node says what it did: NTP source, offset +2 s (measured on loopback: within 50 ms).
            with open_session(SessionSettings(mode="client", connect=[site.endpoint])) as s:
                got: list[NodeStatus] = []
                sub = s.declare_subscriber(
                    site.keys.sensor_status(off), lambda x: got.append(decode(x.payload.to_bytes(), NodeStatus))
                )
                wait_for(lambda: got, 10.0, f"a status from {off}")
                sub.undeclare()
            assert got[-1].clock_source == "ntp", got[-1]
            assert abs(got[-1].clock_offset_ns - 2_000_000_000) < 50_000_000, got[-1]
        assert ntp.requests > 0


# ---------------------------------------------------------------------------
# late and out-of-order frames
# ---------------------------------------------------------------------------


def test_late_and_out_of_order_frames_are_counted_and_tracking_holds(site: FaultSite) -> None:
    """Two extra cameras of the same room (played by the fleet) send every 3rd frame after the
    next one and one frame in 30 300 ms late: the manager counts both kinds, keeps using those
    cameras, and its tracks stay on the people."""
    site.start_router()
    with observing(site) as obs:
        site.start_manager(site.manager_config(extra_sensors=(f"s{SENSORS:02d}", f"s{SENSORS + 1:02d}")))
        for sid in site.ids:
            site.start_node(sid)
        fleet = site._spawn(
            [
                sys.executable,
                "-m",
                "benchmarks.bench_load",
                "fleet",
                "--connect",
                site.endpoint,
                "--prefix",
                site.prefix,
                "--sensors",
                str(SENSORS + 2),
                "--people",
                str(PEOPLE),
                "--seed",
                str(SEED),
                "--fps",
                str(FPS),
                "--duration",
                "0",
                "--only",
                f"s{SENSORS:02d},s{SENSORS + 1:02d}",
                "--epoch-ns",
                str(site.epoch_ns),
                "--reorder",
                "3",
                "--late-ms",
                "300",
            ],
            "fleet",
        )
        extra = {f"s{SENSORS:02d}", f"s{SENSORS + 1:02d}"}
        _up_to_speed(site, obs, need=set(site.ids) | extra)
        t0 = time.monotonic()
        wait_for(lambda: len(obs.status_since(t0)) >= 4, 10.0, "four manager status messages")
        first, last = obs.status_since(t0)[0], obs.status_since(t0)[-1]
        assert last.out_of_order_msgs > first.out_of_order_msgs, (first, last)
        assert last.late_msgs > first.late_msgs, (first, last)
        wait_for(lambda: obs.tracking_with(t0, extra, min_sets=10), 15.0, "the faulty cameras still in use")
        # The tracks stay on the people: confirmed tracks near someone (ground truth scores, never feeds).
        recent = [s for s in obs.sets_since(t0) if obs.confirmed(s)][-20:]
        dists = []
        for ts in recent:
            t_s = (ts.stamp_ns - site.epoch_ns) / 1e9 % LOOP_S
            dists += [
                (round(min(_dist(w, t_s, trk) for w in site.walkers), 2), trk.track_id) for trk in obs.confirmed(ts)
            ]
        near = [d for d, _ in dists if d < 0.5]
        assert dists and len(near) >= 0.8 * len(dists), f"tracks off the people: {sorted(dists)[-10:]}"
        assert fleet.alive, fleet.log()


def _dist(w: Walker, t_s: float, trk: Track) -> float:
    x, y = w.at(t_s)
    return float(((x - trk.x_m) ** 2 + (y - trk.y_m) ** 2) ** 0.5)


# ---------------------------------------------------------------------------
# kill -9 the manager under `panostereo up`
# ---------------------------------------------------------------------------

_TRACK_NUM = re.compile(r"-(\d+)$")


def _track_number(track_id: str) -> int:
    m = _TRACK_NUM.search(track_id)
    return int(m.group(1)) if m else -1


def _child_pid(up_log: ManagedProcess, name: str, after: int = 0) -> int:
    """The pid the supervisor logged for its ``after``-th start of ``name``."""
    pids = [int(m.group(1)) for m in re.finditer(rf"started {re.escape(name)} \(pid (\d+)\)", up_log.stderr_text())]
    return pids[after] if len(pids) > after else 0


def _history(session: Any, keys: Keys, track_id: str, seconds: float) -> list[Track]:
    import zenoh

    selector = zenoh.Selector(keys.track(track_id), {"history": f"{seconds:g}"})
    return [decode(r.ok.payload.to_bytes(), Track) for r in session.get(selector, timeout=3.0) if r.ok is not None]


def test_kill9_manager_under_up_restarts_ids_continue_history_served(site: FaultSite) -> None:
    lines = [f'[site]\nname = "faults"\nprefix = "{site.prefix}"\nrouter = "{site.endpoint}"\n']
    lines.append(f'[[process]]\nname = "manager"\ncommand = "manager"\nconfig = "{site.manager_config()}"\n')
    for sid in site.ids:
        lines.append(f'[[process]]\nname = "{sid}"\ncommand = "node"\nconfig = "{site.node_config(sid)}"\n')
    site_file = site.tmp / "site.toml"
    site_file.write_text("\n".join(lines))
    up = site._spawn(
        [sys.executable, "-m", "panostereo", "up", str(site_file), "--router", "--log-dir", str(site.tmp / "up")], "up"
    )
    wait_for_port(site.port, 20.0, proc=up)
    with observing(site) as obs, open_session(SessionSettings(mode="client", connect=[site.endpoint])) as s:
        _up_to_speed(site, obs)
        t_pre = time.monotonic()
        wait_for(lambda: obs.tracking_with(t_pre, set(site.ids), min_sets=20), 20.0, "two seconds of tracking")
        pre_ids = {t.track_id for ts in obs.sets_since(0) for t in ts.tracks}
        victim_track = max(
            (t for ts in obs.sets_since(t_pre) for t in obs.confirmed(ts)), key=lambda t: t.hits
        ).track_id
        pid = wait_for(lambda: _child_pid(up, "manager"), 5.0, "the manager's pid in the supervisor's log")
        crash_ns = time.time_ns()
        t_kill = time.monotonic()
        os.kill(pid, signal.SIGKILL)
        mgr_key = site.keys.manager(MANAGER_ID)
        wait_for(lambda: obs.alive_change(mgr_key, False, t_kill), 5.0, "the manager's token to go")
        # The supervisor restarts it; it announces itself and tracks again.
        wait_for(lambda: _child_pid(up, "manager", after=1), 15.0, "the supervisor to restart the manager")
        wait_for(lambda: obs.alive_change(mgr_key, True, t_kill), 20.0, "the restarted manager's token")
        t_back = time.monotonic()
        _up_to_speed(site, obs, timeout_s=30.0)
        post_ids = {t.track_id for ts in obs.sets_since(t_back) for t in ts.tracks}
        new_ids = post_ids - pre_ids
        assert new_ids, "no track was born after the restart"
        # Ids continue: everything born after the crash numbers above everything handed out before.
        assert min(map(_track_number, new_ids)) > max(map(_track_number, pre_ids)), (sorted(pre_ids), sorted(new_ids))
        # History from before the crash is still served by the restarted manager.
        past = _history(s, site.keys, victim_track, 600.0)
        assert past, f"no history for {victim_track} after the restart"
        assert all(t.track_id == victim_track for t in past)
        assert any(t.stamp_ns < crash_ns for t in past), "the history holds nothing from before the crash"
        assert [t.stamp_ns for t in past] == sorted(t.stamp_ns for t in past), "history not oldest first"
    assert up.alive, up.log()
    up.signal(signal.SIGTERM)
    assert up.wait(30.0) == 0, up.log()


def test_a_second_process_under_a_running_ones_id_is_refused(site: FaultSite) -> None:
    """A manager and a sensor node started again under the ids of running ones (a config copied, a unit started
    twice) exit with one clear line; the running ones go on, and tracking with them."""
    site.start_router()
    with observing(site) as obs:
        start_tracking(site, obs)
        twins = [site.start_manager(), site.start_node(site.ids[0])]
        for twin in twins:
            assert twin.wait(20.0) == 1, twin.log()
            lines = [ln for ln in twin.stderr_text().splitlines() if "error:" in ln]
            assert len(lines) == 1 and "already runs in this site" in lines[0], twin.log()
        t_after = time.monotonic()
        wait_for(lambda: obs.tracking_with(t_after, set(site.ids)), 20.0, "tracking with every camera after")
        assert all(p.alive for p in site.procs if p not in twins), site.logs()
