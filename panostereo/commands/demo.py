"""``panostereo demo``: run a whole site on this machine, watch it live, and score it.

Usage::

    panostereo demo [--site FILE] [--duration S] [--out DIR] [--seed N] [--listen ENDPOINT]

Starts a zenoh router (``tcp/127.0.0.1:7447`` by default, so other clients can
join) and every ``[[process]]`` of the site as its own OS process, a client of
that router, with a common world epoch (``PANOSTEREO_EPOCH_NS``) for simulated
sources. Records everything into ``OUT/recording.mcap`` while showing the live
view, then stops the processes and writes ``OUT/gt.csv`` (the simulated world's
ground truth -- for scoring only; it never reaches the pipeline), the scores in
``OUT/summary.json`` and the top view ``OUT/top.png``. A dataset site
(``[dataset]``: detection files and a ``gt.csv``) runs the same way.
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import shutil
import sys
import time
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from common.cli import EXIT_ERROR, non_negative, positive
from common.codec import encode
from common.errors import ConfigError, SessionError
from common.keys import Keys
from common.schema import ViewPlan
from common.session import SessionSettings, Shutdown, install_signal_handlers, open_session
from common.site import SiteConfig, load_site
from panostereo.launcher import (
    EPOCH_ENV,
    SEED_ENV,
    START_ENV,
    STATE_ENV,
    ProcessPlan,
    Supervisor,
    process_ids,
    router_plan,
    site_endpoints,
    site_plans,
)

__all__ = ["configure", "default_site", "run"]

logger = logging.getLogger(__name__)

DEFAULT_WARMUP_S = 5.0
WAIT_NOTE_S = 5.0
"""While processes come up, who is still awaited is printed this often (s)."""
VIEW_PERIOD_S = 5.0
"""Without a terminal, a progress line is printed this often (s); the live view refreshes every second."""
STRAYS_NAMED = 10
"""The summary's warning names at most this many sensors the demo did not start (and counts the rest)."""
"""Unscored seconds at the start of a simulated site (background models learning, first tracks)."""
START_LEAD_NS = 500_000_000
"""A dataset site's frame 1 is played this long after the start file is written (every node polls it)."""


def default_site() -> Path:
    """``deploy/sites/demo.toml`` of this checkout."""
    return Path(__file__).resolve().parents[2] / "deploy" / "sites" / "demo.toml"


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--site", default=None, metavar="FILE", help="site file (default deploy/sites/demo.toml)")
    parser.add_argument("--duration", type=float, default=None, help="seconds of tracking (default: the site's)")
    parser.add_argument("--out", default=None, metavar="DIR", help="output folder (default runs/<time>/)")
    parser.add_argument("--seed", type=int, default=None, help="world seed (default: the site's)")
    net = parser.add_mutually_exclusive_group()
    net.add_argument(
        "--listen",
        default=None,
        metavar="ENDPOINT",
        help="where the demo's router listens; every process of the site connects there (default: the site's "
        "router, tcp/127.0.0.1:7447)",
    )
    net.add_argument(
        "--connect",
        default=None,
        metavar="ENDPOINT",
        help="join a router that is already running there instead of starting one",
    )
    parser.add_argument("--threshold", type=positive, default=0.5, help="evaluation match distance (m)")
    parser.add_argument(
        "--ready-timeout",
        type=positive,
        default=60.0,
        help="wait this long for every process to be up (s); a process that exits meanwhile ends the wait at once",
    )
    parser.add_argument(
        "--warmup",
        type=non_negative,
        default=None,
        help="seconds after every process is up that are not scored (background models, track confirmation); "
        "default 5 (at most half the duration), and 0 on a dataset site, which plays from its frame 1 once every "
        "process is up",
    )
    parser.add_argument("--no-view", action="store_true", help="no live view (progress lines only)")


def goals_from_plans(plans: Iterable[ViewPlan], epoch_ns: int, mobile: set[str]) -> list[Any]:
    """Goals the simulated robots received, by the one rule the sim nodes use (sim.world)."""
    from sim.driver import goals_from_plans as shared

    return list(shared([p for p in plans if p.sensor_id in mobile], epoch_ns))


def _wait_router(router: Supervisor, endpoint: str, log: Path, timeout_s: float = 15.0) -> None:
    """Wait until our router says it listens; fail clearly if it died (port taken by another router?).

    Connecting is not proof: another router on the same port would accept too.
    """
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        router.poll()
        text = log.read_text(errors="replace") if log.exists() else ""
        if not router.alive("router"):
            tail = text.strip().splitlines()[-1:]
            raise SessionError(f"the demo's router could not start on {endpoint}: {' '.join(tail) or 'it exited'}")
        if "listening on" in text:
            return
        time.sleep(0.1)
    raise SessionError(f"the demo's router did not report listening on {endpoint} within {timeout_s:g} s")


def _start_dataset(path: Path) -> int:
    """Write the start file recorded sources wait for: frame 1 a moment from now (every node reads it first).

    Returns:
        The epoch written (Unix ns of frame 1).
    """
    epoch_ns = time.time_ns() + START_LEAD_NS
    tmp = path.with_suffix(".tmp")
    tmp.write_text(str(epoch_ns), encoding="utf-8")
    tmp.replace(path)  # atomic: a node never reads half a number
    return epoch_ns


def _sources_ended(views: Iterable[Any], sensors: set[str]) -> bool:
    """Every sensor node of the site says its source ended (videos, image folders, detection files)."""
    ended = {v.sensor_id for v in views if v.status is not None and v.status.source_state == "ended"}
    return bool(sensors) and sensors <= ended


def _progress(elapsed: float, duration: float, client: Any) -> str:
    tracks = client.tracks(timeout_s=0)
    return f"demo {elapsed:5.1f}/{duration:.0f} s  tracks {len(tracks)}"


def recorded_keys(keys: Keys, sensors: list[str]) -> list[str]:
    """What the demo records: everything of its own sensors, managers, tracks and plans.

    Not ``{root}/**``: whatever another client publishes under other sensor ids (a stray camera, a flood of
    fresh ids) is then never routed to the recorder at all; the manager counts it (``ManagerStatus.refused``)
    and the summary names those senders.
    """
    return [
        keys.tracks(),
        keys.all_tracks,
        keys.all_plans,
        f"{keys.root}/manager/**",
        *(f"{keys.sensor(sid)}/**" for sid in sensors),
    ]


def _recorder_line(recorder: Any) -> str:
    st = recorder.status()
    lost = f"LOST {st.dropped} ({st.dropped_raw} raw sensor messages)" if st.dropped else "nothing lost"
    top = recorder.top_drops()
    most = "; most on " + ", ".join(f"{k or '(other keys)'} {n}" for k, n in top) if top else ""
    return f"recording: {st.written} samples, {lost}, {st.lag_s:.1f} s behind (worst {st.max_lag_s:.1f} s){most}"


def _run_times(site: SiteConfig, args: argparse.Namespace) -> tuple[float, float]:
    """The run's duration and scoring warm-up (s): the flags, else the dataset's length, else the site's.

    Raises:
        ConfigError: a duration that is not positive, or a warm-up outside [0, duration).
    """
    dataset = site.dataset
    if args.duration is not None:
        duration = float(args.duration)
    elif dataset is not None and dataset.frames:
        duration = dataset.frames / dataset.fps + 1.0
    else:
        duration = site.site.duration_s
    if not (duration > 0 and math.isfinite(duration)):
        raise ConfigError(f"--duration must be a positive number of seconds, got {duration}")
    if args.warmup is not None:
        warmup = float(args.warmup)
    elif dataset is not None:
        warmup = 0.0
    else:  # the default never refuses a short run: half of it is scored at least
        warmup = min(DEFAULT_WARMUP_S, duration / 2)
    if not 0 <= warmup < duration:
        raise ConfigError(f"--warmup must be in [0, duration={duration:g}) s, got {warmup}")
    return duration, warmup


def _wait_ready(
    client: Any,
    procs: Supervisor,
    sensors: set[str],
    managers: set[str],
    *,
    shutdown: Shutdown,
    timeout_s: float,
    seen_alive: set[str],
) -> str:
    """Wait until every sensor and manager of the site is alive, and every manager has heard what each of its
    sensors is (its status lists them as known: frames that came before would be held back or fused without
    them), saying who it waits for now and then.

    Returns:
        ``ready``; ``failed`` as soon as a process has exited (it crashed or refused its config: waiting longer
        cannot help); ``timeout``; or ``interrupted``. ``seen_alive`` collects the sensors seen up.
    """
    t0 = time.monotonic()
    last_wait_note = t0
    while not shutdown.is_set() and time.monotonic() - t0 < timeout_s:
        procs.poll()
        if procs.exited():
            return "failed"
        up_s = {s.sensor_id for s in client.sensors(timeout_s=0.5) if s.alive}
        seen_alive |= up_s
        views = client.managers(timeout_s=0.5)
        up_m = {
            m.manager_id for m in views if m.alive and m.status is not None and _knows_its_sensors(m.status, sensors)
        }
        if sensors <= up_s and managers <= up_m:
            return "ready"
        if time.monotonic() - last_wait_note >= WAIT_NOTE_S:
            last_wait_note = time.monotonic()
            print(f"waiting for {sorted((sensors - up_s) | (managers - up_m))} ...", flush=True)
        shutdown.sleep(0.5)
    return "interrupted" if shutdown.is_set() else "timeout"


def _start_failures(procs: Supervisor, log_dir: Path) -> dict[str, dict[str, Any]]:
    """What each process that exited during start-up said last: its exit code, the error line and its log's end."""
    out: dict[str, dict[str, Any]] = {}
    for name, rc in procs.exited().items():
        tail = procs.log_tail(name)
        errors = [line for line in tail if "error" in line.lower()]
        out[name] = {
            "exit_code": rc,
            "reason": (errors or tail or ["(no output)"])[-1],
            "log": str(log_dir / f"{name}.log"),
            "log_tail": tail,
        }
    return out


def _knows_its_sensors(status: Any, sensors: set[str]) -> bool:
    """Whether a manager's status says it knows every one of the site's sensors it expects."""
    expected = set(status.sensors_expected) & sensors if status.sensors_expected else sensors
    return expected <= set(status.sensors_known)


def _watch_run(
    client: Any,
    procs: Supervisor,
    recorder: Any,
    sensors: set[str],
    shutdown: Shutdown,
    *,
    duration: float,
    tty: bool,
    title: str,
) -> None:
    """Supervise the run for ``duration`` (or until every source ended), showing the live view or progress."""
    from user_agent.views import CLEAR_SCREEN, watch_screen

    start = time.monotonic()
    last_view = last_ended = 0.0
    while not shutdown.is_set():
        procs.poll()
        elapsed = time.monotonic() - start
        if elapsed >= duration:
            break
        if time.monotonic() - last_ended >= 1.0:
            last_ended = time.monotonic()
            if _sources_ended(client.sensors(timeout_s=0.3), sensors):
                print("every sensor's source has ended (end of its file): stopping", flush=True)
                break
        if time.monotonic() - last_view >= (1.0 if tty else VIEW_PERIOD_S):
            last_view = time.monotonic()
            if tty:
                head = f"panostereo demo  {elapsed:5.1f}/{duration:.0f} s  {title}"
                footer = ["", _recorder_line(recorder)]
                views = client.sensors(timeout_s=0.3)
                tracks, managers = client.tracks(timeout_s=0), client.managers(0.3)
                print(CLEAR_SCREEN + watch_screen(tracks, views, managers, head, footer=footer), flush=True)
            else:
                print(f"{_progress(elapsed, duration, client)}  {_recorder_line(recorder)}", flush=True)
        shutdown.sleep(0.2)


def _run_facts(site: SiteConfig, epoch_ns: int, fps: float) -> dict[str, str]:
    """The run's facts, stored in the recording (``panostereo`` metadata)."""
    meta = {"site": site.site.name, "prefix": site.site.prefix, "epoch_ns": str(epoch_ns), "fps": str(fps),
            "seed": str(site.site.seed)}  # fmt: skip
    if site.dataset is None:
        meta |= {"room_x_m": str(site.world.room_x_m), "room_y_m": str(site.world.room_y_m)}
    if site.area is not None:
        meta["area"] = json.dumps(site.area.polygon)
    return meta


def _mark_start(client: Any, sink: Any, keys: Keys, start_file: Path | None, *, epoch_ns: int, warmup_s: float) -> int:
    """Once every process is up: record the sensors' poses, start a dataset's playback (``start_file``), and
    store where scoring starts. Returns the run's epoch (a dataset's: when its frame 1 plays)."""
    for view in client.sensors(timeout_s=1.0):  # make sure the poses are in the file
        if view.info is not None:
            sink.write(keys.sensor_info(view.sensor_id), encode(view.info), time.time_ns())
    if start_file is not None:
        epoch_ns = _start_dataset(start_file)
        sink.add_metadata("panostereo.dataset", {"epoch_ns": str(epoch_ns)})
    score_from_ns = max(time.time_ns(), epoch_ns) + int(warmup_s * 1e9)
    sink.add_metadata("panostereo.scoring", {"score_from_ns": str(score_from_ns), "warmup_s": str(warmup_s)})
    return epoch_ns


@dataclass(frozen=True, slots=True)
class _Setup:
    """What the run needs, worked out from the site and the flags before anything starts."""

    site: SiteConfig
    fps: float
    duration_s: float
    warmup_s: float
    out: Path
    listen: str | None
    """Where the demo's router listens (``None``: it joins a running router)."""
    endpoint: str
    """Where every process of the site, and the demo itself, connects."""
    epoch_ns: int
    start_file: Path | None
    """A dataset site's start file (its frame 1 plays at the epoch written there); ``None`` on a simulated site."""
    log_dir: Path
    plans: list[ProcessPlan]
    keys: Keys
    meta: dict[str, str]
    sensors: set[str]
    managers: set[str]


def _prepare(site: SiteConfig, args: argparse.Namespace) -> _Setup:
    """Work out the run's times, output folder, endpoints, environment and process plans (creates ``out``).

    Raises:
        ConfigError: bad times, or a site with no process to run on this machine.
    """
    dataset = site.dataset
    fps = dataset.fps if dataset is not None else site.site.fps
    duration, warmup = _run_times(site, args)
    out = Path(args.out or Path("runs") / time.strftime("%Y%m%d-%H%M%S")).resolve()
    out.mkdir(parents=True, exist_ok=True)
    ids = process_ids(site)
    listen, connect = site_endpoints(site, listen=args.listen, connect=args.connect, router=args.connect is None)
    assert connect is not None  # the demo always says where its processes connect
    epoch_ns = time.time_ns()
    env = {EPOCH_ENV: str(epoch_ns), SEED_ENV: str(site.site.seed), STATE_ENV: str(out / "state")}
    start_file = out / "start_ns"
    if dataset is not None:
        # Recorded sources wait for this file and play their frame 1 at the epoch it holds (_mark_start writes it).
        start_file.unlink(missing_ok=True)
        env[START_ENV] = str(start_file)
    log_dir = out / "logs"
    plans = site_plans(site, connect=connect, env=env, log_dir=log_dir)
    if not plans:
        raise ConfigError(f"{site.path}: no [[process]] to run on localhost")
    return _Setup(
        site=site,
        fps=fps,
        duration_s=duration,
        warmup_s=warmup,
        out=out,
        listen=listen,
        endpoint=connect,
        epoch_ns=epoch_ns,
        start_file=start_file if dataset is not None else None,
        log_dir=log_dir,
        plans=plans,
        keys=Keys(site.site.prefix),
        meta=_run_facts(site, epoch_ns, fps),
        sensors={i for c, i in ids.values() if c == "node"},
        managers={i for c, i in ids.values() if c == "manager"},
    )


@dataclass(frozen=True, slots=True)
class _Attended:
    """What watching the site leaves for the summary (or, when a process failed to start, for the failure report)."""

    failed: dict[str, dict[str, Any]]
    """Processes that exited while the site was coming up (:func:`_start_failures`); empty when it ran."""
    epoch_ns: int
    """The run's epoch (a dataset's: when its frame 1 played)."""
    t_stop_ns: int
    last_status: dict[str, Any]
    """Manager id -> its last status."""
    seen_sensors: set[str]
    seen_alive: set[str]


def _attend(
    client: Any,
    procs: Supervisor,
    recorder: Any,
    setup: _Setup,
    shutdown: Shutdown,
    *,
    ready_timeout_s: float,
    tty: bool,
) -> _Attended:
    """Start the site's processes, wait until they are up, mark the start and watch the run to its end."""
    seen_alive: set[str] = set()
    procs.start()
    wait = _wait_ready(
        client,
        procs,
        setup.sensors,
        setup.managers,
        shutdown=shutdown,
        timeout_s=ready_timeout_s,
        seen_alive=seen_alive,
    )
    if wait == "failed":
        failed = _start_failures(procs, setup.log_dir)
        return _Attended(
            failed=failed,
            epoch_ns=setup.epoch_ns,
            t_stop_ns=setup.epoch_ns,
            last_status={},
            seen_sensors=set(),
            seen_alive=seen_alive,
        )
    if wait == "timeout":
        logger.warning("not every process came up within %.0f s; running anyway", ready_timeout_s)
    epoch_ns = _mark_start(
        client, recorder.sink, setup.keys, setup.start_file, epoch_ns=setup.epoch_ns, warmup_s=setup.warmup_s
    )
    title = f"site {setup.site.site.name}  out {setup.out}"
    _watch_run(client, procs, recorder, setup.sensors, shutdown, duration=setup.duration_s, tty=tty, title=title)
    t_stop_ns = time.time_ns()
    last_status = {m.manager_id: m.status for m in client.managers(0.5) if m.status is not None}
    views = client.sensors(timeout_s=0.5)
    seen_alive |= {v.sensor_id for v in views if v.alive}
    return _Attended(
        failed={},
        epoch_ns=epoch_ns,
        t_stop_ns=t_stop_ns,
        last_status=last_status,
        seen_sensors={v.sensor_id for v in views},
        seen_alive=seen_alive,
    )


def _run_site(
    setup: _Setup, procs: Supervisor, shutdown: Shutdown, *, ready_timeout_s: float, tty: bool
) -> tuple[Any, _Attended]:
    """Run the site under the demo's router, recording it, and stop it all in reverse order.

    Returns the recorder, its sink left open (the ground truth is added after the run; on an error it is closed
    here), and what the run left.
    """
    from user_agent.client import AgentClient
    from user_agent.record import McapSink, Recorder

    router_log = setup.log_dir / "router.log"
    listen = setup.listen
    router = Supervisor([router_plan([listen], log_path=router_log)] if listen else [], restart=False, grace_s=3.0)
    router.start()
    sink: Any = None
    sensors = sorted(setup.sensors)
    try:
        if listen:
            _wait_router(router, setup.endpoint, router_log)
        settings = SessionSettings(connect=[setup.endpoint], connect_timeout_ms=15_000)
        with open_session(settings) as session:
            recording = setup.out / "recording.mcap"
            recorder = Recorder(session, recorded_keys(setup.keys, sensors), McapSink(recording, setup.meta))
            sink = recorder.sink
            client = AgentClient(session=session, prefix=setup.site.site.prefix, agent_id="demo", sensors=sensors)
            try:
                attended = _attend(client, procs, recorder, setup, shutdown, ready_timeout_s=ready_timeout_s, tty=tty)
            finally:
                recorder.stop(close=False)  # the ground-truth scene is added before the file is finished
                client.close()
                procs.stop()
    except BaseException:
        if sink is not None:
            sink.close()
        raise
    finally:
        router.stop()
    return recorder, attended


def run(args: argparse.Namespace) -> int:
    """Run the demo; returns 0 when it completed (whatever the scores), 1 when a process could not start.

    The site's life cycle in order: work out the run, start the router, recorder and processes, watch them
    (:func:`_run_site`), then score and report.
    """
    from sim.world import site_with_seed

    site = site_with_seed(load_site(args.site or default_site()), args.seed)
    setup = _prepare(site, args)
    shutdown = install_signal_handlers()
    procs = Supervisor(setup.plans, backoff_min_s=1.0, max_restarts=3, grace_s=5.0)
    tty = sys.stdout.isatty() and not args.no_view
    recorder, attended = _run_site(setup, procs, shutdown, ready_timeout_s=args.ready_timeout, tty=tty)
    sink = recorder.sink
    if attended.failed:
        sink.close()
        return _report_failure(site, setup.out, attended.failed, sensors=setup.sensors, started=attended.seen_alive)
    try:
        ran = _Ran(
            epoch_ns=attended.epoch_ns,
            t_stop_ns=attended.t_stop_ns,
            restarts=procs.restarts(),
            cameras=Cameras(site=setup.sensors, started=attended.seen_alive),
            recorder=recorder.status(),
            refused=_refusals(attended.last_status),
            sightings_refused=_sightings_refused(attended.last_status),
            seen_sensors=attended.seen_sensors,
            interrupted=shutdown.is_set(),
        )
        return _finish(site, sink=sink, out=setup.out, fps=setup.fps, threshold_m=args.threshold, ran=ran)
    finally:
        sink.close()


@dataclass(frozen=True, slots=True)
class Cameras:
    """The site's sensor nodes, and those seen up (their liveliness token) during the run."""

    site: set[str]
    started: set[str]


def _report_failure(
    site: SiteConfig, out: Path, failed: dict[str, dict[str, Any]], *, sensors: set[str], started: set[str]
) -> int:
    """A process exited while the site was coming up: say which and why, write it in the summary, exit 1."""
    summary = {
        "failed_to_start": failed,
        "site": site.site.name,
        "cameras": {"site": len(sensors), "started": len(started & sensors), "publishing": 0, "fused": 0},
        "logs": str(out / "logs"),
    }
    (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n", encoding="utf-8")
    for name, why in failed.items():
        print(f"ERROR: {name} exited with code {why['exit_code']} while the site was starting: {why['reason']}")
        print(f"  the end of {why['log']}:")
        for line in why["log_tail"]:
            print(f"    {line}")
    print(f"summary: {out / 'summary.json'}")
    return EXIT_ERROR


def _platform_paths(world: Any, t1_s: float) -> dict[str, list[tuple[float, float]]]:
    """True camera platform paths over the run (simulation truth, for the plot's truth panel)."""
    paths: dict[str, list[tuple[float, float]]] = {}
    for i in range(61):
        for p in world.platforms_at(max(0.0, t1_s * i / 60)):
            paths.setdefault(p.sensor_id, []).append((p.x_m, p.y_m))
    return paths


def _write_truth_scene(sink: Any, gt: Any, epoch_ns: int, fps: float) -> None:
    """Ground-truth people as ``/scene/ground_truth`` (foxglove.SceneUpdate), to compare with the tracks in Foxglove.

    Written after the run, on its own channel (``kind=extra``): replay republishes raw channels only, so the
    truth never reaches a pipeline.
    """
    from user_agent.foxglove import truth_scene

    for k in gt.frame_numbers:
        stamp = epoch_ns + round((k - 1) / fps * 1e9)
        people = [(p.person_id, p.x_m, p.y_m, p.z_m) for p in gt.frames[k]]
        scene = truth_scene(people, stamp, lifetime_s=1.5 / fps)
        sink.add_foxglove("/scene/ground_truth", scene, stamp)


@dataclass(frozen=True, slots=True)
class _Ran:
    """What the run leaves for its summary besides the recording."""

    epoch_ns: int
    t_stop_ns: int
    restarts: dict[str, int]
    cameras: Cameras
    recorder: Any
    """The recorder's last status (what it wrote and lost), or ``None``."""
    refused: dict[str, Refused]
    sightings_refused: dict[str, int]
    seen_sensors: set[str]
    interrupted: bool


def _write_ground_truth(
    site: SiteConfig, sink: Any, gt_path: Path, *, epoch_ns: int, t_stop_ns: int, fps: float
) -> dict[str, list[tuple[float, float]]] | None:
    """Write ``gt.csv``: a dataset's copied, a simulated world's replayed with the goals its robots got.

    Returns:
        The camera platforms' true paths on a simulated site (for the plot), ``None`` on a dataset site.

    Raises:
        ConfigError: a dataset site whose ground truth is missing.
    """
    if site.dataset is not None:
        src = site.resolve(site.dataset.ground_truth)
        if not src.is_file():
            raise ConfigError(f"{site.path}: dataset.ground_truth {site.dataset.ground_truth!r} not found ({src})")
        shutil.copyfile(src, gt_path)
        return None
    from sim.world import World, write_gt_csv

    world = World.from_site(site).with_goals(
        goals_from_plans(sink.plans, epoch_ns, {c.id for c in site.camera if c.mobile})
    )
    write_gt_csv(world, gt_path, fps, (t_stop_ns - epoch_ns) / 1e9 + 1.0)
    return _platform_paths(world, (t_stop_ns - epoch_ns) / 1e9)


def _summary(site: SiteConfig, rec: Any, gt: Any, scored: Any, ran: _Ran, *, files: dict[str, str]) -> dict[str, Any]:
    """The run's summary: cameras that started, published and were fused; the scores; what was lost or refused.

    ``files`` holds the paths of the ``recording``, the ``plot`` and the ``ground_truth``.
    """
    m = scored.metrics
    started = ran.cameras.site
    seen = set(rec.sensor_infos) | set(rec.node_status) | ran.seen_sensors
    publishing = {sid for sid, n in rec.frames.items() if n > 0} & started
    fused = {sid for ts in rec.tracksets for sid in ts.sensors_used} & started
    metrics = m.to_dict()
    recorder = ran.recorder
    lost = {
        "dropped": recorder.dropped if recorder else 0,
        "dropped_raw": recorder.dropped_raw if recorder else 0,
        "max_lag_s": round(recorder.max_lag_s, 2) if recorder else 0.0,
        "unscored_s": round(scored.unseen_s, 2),
    }
    return {
        "cameras": {
            "site": len(started),
            "started": len(ran.cameras.started & started),
            "publishing": len(publishing),
            "fused": len(fused),
        },
        "cameras_silent": sorted(started - publishing),
        "people": m.gt_ids if m.frames else len(gt.person_ids),
        "frames": m.frames,
        "tracks_published": scored.tracks_published,
        **{k: metrics[k] for k in _SUMMARY_METRICS},
        **files,
        **{k: metrics[k] for k in _EXTRA_METRICS},
        "site": site.site.name,
        "seed": site.site.seed,
        "duration_s": round((ran.t_stop_ns - ran.epoch_ns) / 1e9, 2),
        "scored_from_s": round((rec.meta_int("score_from_ns", ran.epoch_ns) - ran.epoch_ns) / 1e9, 2),
        "recorded_samples": rec.samples,
        "recording_lost": lost,
        "sensors_not_started": sorted((seen | set(ran.refused)) - started),
        "refused_by_manager": _split_refusals(ran.refused)[0],
        "refused_by_clock": _split_refusals(ran.refused)[1],
        "sightings_refused": ran.sightings_refused,
        "restarts": ran.restarts,
        "interrupted": ran.interrupted,
    }


def _report(summary: dict[str, Any], out: Path, ran: _Ran) -> None:
    """Write ``summary.json``, print it, then what its reader must not miss, then where it is."""
    (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n", encoding="utf-8")
    print(json.dumps(summary, indent=2))
    strays = summary["sensors_not_started"]
    for level, line in _warnings(summary["recording_lost"], strays, ran.refused, ran.cameras.site):
        print(f"{level}: {line}")
    if ran.interrupted:
        print(f"NOTE: the run was interrupted after {summary['duration_s']} s: the figures cover what ran")
    print(f"summary: {out / 'summary.json'}")


def _finish(site: SiteConfig, *, sink: Any, out: Path, fps: float, threshold_m: float, ran: _Ran) -> int:
    """Write the ground truth into ``gt.csv`` and the recording, score and plot the recording, and report; 0."""
    from user_agent.groundtruth import read_gt_csv
    from user_agent.recording import load_recording
    from user_agent.report import plot_recording, score_recording

    gt_path = out / "gt.csv"
    recording = out / "recording.mcap"
    gt_cameras = _write_ground_truth(site, sink, gt_path, epoch_ns=ran.epoch_ns, t_stop_ns=ran.t_stop_ns, fps=fps)
    gt = read_gt_csv(gt_path)
    _write_truth_scene(sink, gt, ran.epoch_ns, fps)
    sink.close()
    rec = load_recording(recording)
    area = gt.area() if site.dataset is not None and site.dataset.scored_area == "ground_truth" else None
    scored = score_recording(rec, gt, threshold_m=threshold_m, area=area)
    m = scored.metrics
    plot = plot_recording(
        rec,
        out / "top.png",
        gt,
        title=f"{site.site.name}  MOTA {m.mota:.3f}  IDF1 {m.idf1:.3f}  id switches {m.id_switches}",
        gt_cameras=gt_cameras,
        threshold_m=threshold_m,
        scored_area=area,
    )
    files = {"recording": str(recording), "plot": str(plot), "ground_truth": str(gt_path)}
    _report(_summary(site, rec, gt, scored, ran, files=files), out, ran)
    return 0


Refused = dict[str, int]
"""One sender's refused messages by reason (``unlisted``, ``wrong_id``, ``late``, ``ahead``), nonzero ones only."""
IMPOSTOR_REASONS = ("unlisted", "wrong_id")
"""What only a sender that is not who it says does (or a misconfigured one); late and ahead frames are a loaded
host's or an unsynchronised clock's doing as well."""


def _refusals(statuses: dict[str, Any]) -> dict[str, Refused]:
    """Sender id -> the messages the managers refused from it, by reason (their last status)."""
    out: dict[str, Refused] = {}
    for st in statuses.values():
        for r in st.refused:
            row = out.setdefault(r.sender_id, {})
            for reason, n in (("unlisted", r.unlisted), ("wrong_id", r.wrong_id), ("late", r.skewed),
                              ("ahead", r.ahead)):  # fmt: skip
                if n:
                    row[reason] = row.get(reason, 0) + n
    return {sid: row for sid, row in out.items() if row}


def _sightings_refused(statuses: dict[str, Any]) -> dict[str, int]:
    """Sender id -> instants at which the managers refused its sightings of another camera (their last status):
    a person hiding part of a robot's band makes a few; a camera lying about another, many."""
    out: dict[str, int] = {}
    for st in statuses.values():
        for r in st.refused:
            if r.sighting:
                out[r.sender_id] = out.get(r.sender_id, 0) + r.sighting
    return out


def _split_refusals(refused: dict[str, Refused]) -> tuple[dict[str, Refused], dict[str, Refused]]:
    """(impostor refusals, clock refusals): who sent as someone else, and whose frames were late or ahead."""
    impostor = {s: {k: n for k, n in r.items() if k in IMPOSTOR_REASONS} for s, r in refused.items()}
    clock = {s: {k: n for k, n in r.items() if k not in IMPOSTOR_REASONS} for s, r in refused.items()}
    return {s: r for s, r in impostor.items() if r}, {s: r for s, r in clock.items() if r}


def _warnings(
    lost: dict[str, Any], strays: list[str], refused: dict[str, Refused], started: set[str]
) -> list[tuple[str, str]]:
    """(level, text): what the summary's reader must not miss: a recording that lost data, sensors nobody
    started, messages forged under the site's own ids; and, as notes, frames refused for their stamps."""
    out = []
    if lost["dropped"]:
        out.append((
            "WARNING",
            f"the recording lost {lost['dropped']} samples ({lost['dropped_raw']} raw sensor messages) to stay near "
            f"live; {lost['unscored_s']} s whose tracks it lost were not scored",
        ))  # fmt: skip
    elif lost["unscored_s"]:
        out.append(
            ("WARNING", f"{lost['unscored_s']} s of the run's tracks never reached the recording and were not scored")
        )
    if strays:
        n = STRAYS_NAMED
        shown = ", ".join(strays[:n]) + (f" and {len(strays) - n} more" if len(strays) > n else "")
        out.append((
            "WARNING",
            f"sensors this demo did not start were on its network: {shown} "
            f"(the manager fuses only {', '.join(sorted(started))})",
        ))  # fmt: skip
    impostor, clock = _split_refusals(refused)
    mine = {sid: r for sid, r in impostor.items() if sid in started}
    if mine:
        out.append(
            ("WARNING", f"the manager refused messages under the site's own ids (forged or misconfigured): {mine}")
        )
    for sid, r in sorted(clock.items()):
        if sid not in started:
            continue
        if r.get("late"):
            out.append((
                "NOTE",
                f"the manager refused {r['late']} late frame(s) of {sid}: stamped more than its max_skew_s behind "
                "its clock (a loaded machine, or the camera's clock is behind)",
            ))  # fmt: skip
        if r.get("ahead"):
            out.append((
                "WARNING",
                f"the manager refused {r['ahead']} frame(s) of {sid} stamped ahead of its clock by more than its "
                "max_lead_s: is that host's clock synchronised (agent sensors shows the offsets)?",
            ))  # fmt: skip
    return out


_SUMMARY_METRICS = ("mota", "motp_m", "idf1", "id_switches", "mean_error_m", "p90_error_m")
_EXTRA_METRICS = ("precision", "recall", "false_positives", "misses", "objects", "threshold_m")
