"""``user-agent`` (= ``panostereo agent``): watch, tracks, history, sensors, view, record, replay, plot, evaluate.

Thin entry point: parse, load config, call the library, print. Network
subcommands take the shared zenoh flags (``--connect`` …) and ``--config``
(an agent TOML with ``[agent]`` and ``[zenoh]``).
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import sys
import time
from collections.abc import Callable
from typing import Any, TypeAlias

import msgspec

from common.cli import exit_process, non_negative, positive, run_command
from common.errors import ConfigError
from common.keys import DEFAULT_PREFIX, Keys, validate_id
from common.session import SessionSettings, add_session_args, install_signal_handlers, open_session, settings_from_args

__all__ = ["configure", "main", "run"]

logger = logging.getLogger(__name__)

EPOCH_ENV = "PANOSTEREO_EPOCH_NS"
STATUS_WAIT_S = 2.5
"""`watch` and `sensors` wait up to this long for every live sensor's and manager's status (1 Hz) before they show
them: two and a half periods, so a status put just before the agent subscribed is not missed."""
TRACKS_WAIT_S = 1.0
"""`sensors` waits up to this long for the managers' TrackSets (one per fusion tick)."""
SENSORS_REFRESH_S = 3.0
"""`watch` asks for the sensors again this often (s); tracks and managers every screen."""


def _net(p: argparse.ArgumentParser) -> None:
    p.add_argument("--config", default=None, metavar="FILE", help="agent config (TOML: [agent] id, prefix; [zenoh])")
    p.add_argument("--prefix", default=None, help=f"key prefix of the site (default {DEFAULT_PREFIX})")
    p.add_argument("--agent-id", default=None, help="id announced on the network (default agent-<pid>)")
    add_session_args(p)


Subparsers: TypeAlias = "argparse._SubParsersAction[argparse.ArgumentParser]"
"""What ``add_subparsers`` returns: the agent's actions are added to it."""


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the agent's subcommands to ``parser`` (used by ``panostereo agent`` too)."""
    sub = parser.add_subparsers(dest="action", required=True, metavar="ACTION")
    _add_live_actions(sub)
    _add_recording_actions(sub)
    _add_offline_actions(sub)


def _add_live_actions(sub: Subparsers) -> None:
    """The actions that ask the running network: watch, tracks, history, sensors, view."""
    p = sub.add_parser("watch", help="live terminal view of tracks, sensors and managers")
    p.add_argument("--interval", type=positive, default=0.5, help="refresh period in seconds")
    p.add_argument("--duration", type=non_negative, default=0.0, help="stop after this many seconds (0: until Ctrl-C)")
    p.add_argument("--once", action="store_true", help="print one screen and exit")
    _net(p)

    p = sub.add_parser("tracks", help="current tracks (table or --json)")
    p.add_argument("--json", action="store_true", help="print the tracks as JSON (the fields of pano.Track)")
    p.add_argument("--timeout", type=non_negative, default=3.0, help="wait this long for a first TrackSet (s)")
    _net(p)

    p = sub.add_parser("history", help="a track's path over the last seconds (table or --json)")
    p.add_argument("track_id", help="the track's id (as agent tracks shows it, e.g. mgr1-3)")
    p.add_argument("--seconds", type=positive, default=30.0, help="how far back (s, default 30)")
    p.add_argument("--json", action="store_true", help="print the path as JSON (one pano.Track per state)")
    p.add_argument("--timeout", type=non_negative, default=3.0, help="wait this long for the manager's answer (s)")
    _net(p)

    p = sub.add_parser("sensors", help="sensors with info, status and clock offsets, the tracks and the managers")
    p.add_argument("--json", action="store_true", help="print the sensors as JSON (info, status, clock offset)")
    _net(p)

    p = sub.add_parser(
        "view", help="hold a PTZ view of a track while this runs (renewed; released on exit), or --release one"
    )
    p.add_argument("track_id", help="the track to view (e.g. mgr1-3)")
    p.add_argument(
        "--release", action="store_true", help="release the view held under --agent-id (a running `view` elsewhere)"
    )
    p.add_argument("--priority", type=int, default=0, help="a higher priority takes a camera from a lower one")
    p.add_argument("--manager", default=None, help="manager id (default: from the track id)")
    p.add_argument(
        "--duration", type=non_negative, default=0.0, help="hold the view this many seconds (0: until Ctrl-C)"
    )
    _net(p)


def _add_recording_actions(sub: Subparsers) -> None:
    """The actions that take the network's messages out or put them back: record, replay, foxglove."""
    p = sub.add_parser("record", help="record everything under {prefix}/@v1/** (or --keys) into MCAP")
    p.add_argument("out", metavar="OUT.mcap", help="the recording to write")
    p.add_argument(
        "--keys",
        action="append",
        default=None,
        metavar="PATTERN",
        help="record only these key expressions under {prefix}/@v1/ (e.g. tracks, 'track/*', 'manager/*/status'); "
        "repeatable (default: everything)",
    )
    p.add_argument("--duration", type=non_negative, default=0.0, help="stop after this many seconds (0: until Ctrl-C)")
    p.add_argument(
        "--site",
        default=None,
        metavar="FILE",
        help="site file: stores prefix, fps, room and area for evaluate and plot",
    )
    p.add_argument("--epoch-ns", type=int, default=None, help=f"world epoch (default: env {EPOCH_ENV})")
    p.add_argument("--fps", type=positive, default=None, help="ground-truth frame rate (default: the site's)")
    _net(p)

    p = sub.add_parser("replay", help="republish a recording with its original timing")
    p.add_argument("input", metavar="IN.mcap", help="the recording")
    p.add_argument("--speed", type=positive, default=1.0, help="playback speed (2: twice as fast; default 1)")
    _net(p)

    p = sub.add_parser("foxglove", help="serve the live 3D scene to Foxglove over WebSocket")
    p.add_argument("--host", default="127.0.0.1", help="WebSocket listen address")
    p.add_argument("--port", type=int, default=8765, help="WebSocket port (0: any free port)")
    p.add_argument("--duration", type=non_negative, default=0.0, help="stop after this many seconds (0: until Ctrl-C)")
    _net(p)


def _add_offline_actions(sub: Subparsers) -> None:
    """The actions on a recording, with no network: plot, export, evaluate."""
    p = sub.add_parser("plot", help="picture of a recording: top view (ground truth beside it) and a timeline")
    p.add_argument("input", metavar="IN.mcap", help="the recording (a demo run's, or agent record's)")
    p.add_argument("--out", required=True, metavar="PNG", help="the picture to write")
    p.add_argument(
        "--ground-truth",
        default=None,
        metavar="GT.csv",
        help="frame,id,x_m,y_m: one timeline row per person, who was followed by which track (default: one row "
        "per track)",
    )
    p.add_argument("--title", default="", help="a title above the picture")
    p.add_argument("--threshold", type=positive, default=0.5, help="with --ground-truth: match distance (m)")
    p.add_argument("--epoch-ns", type=int, default=None, help="world epoch (default: from the recording)")
    p.add_argument("--fps", type=positive, default=None, help="ground-truth fps (default: from the recording)")

    p = sub.add_parser("export", help="write a recording's tracks as CSV or MOTChallenge rows (no ground truth needed)")
    p.add_argument("input", metavar="IN.mcap", help="the recording (a demo run's, agent record's, a dataset's)")
    p.add_argument("--out", required=True, metavar="FILE", help="the table to write")
    p.add_argument(
        "--format",
        choices=["csv", "mot"],
        default="csv",
        help="csv: frame,time_s,id,x_m,y_m,height_m,vx_mps,vy_mps,state,manager_id (default); mot: MOTChallenge "
        "3D-style frame,id,-1,-1,-1,-1,1,x,y,z",
    )

    p = sub.add_parser("evaluate", help="MOTA/MOTP, IDF1, ID switches, precision, recall, error of a recording")
    p.add_argument("input", metavar="IN.mcap", help="the recording")
    p.add_argument("--ground-truth", required=True, metavar="GT.csv", help="frame,id,x_m,y_m[,z_m], 1-based frames")
    p.add_argument("--threshold", type=positive, default=0.5, help="match distance in metres")
    p.add_argument("--json", action="store_true", help="print the figures as JSON")
    p.add_argument("--epoch-ns", type=int, default=None, help="world epoch (default: from the recording)")
    p.add_argument("--fps", type=positive, default=None, help="ground-truth fps (default: from the recording)")
    p.add_argument(
        "--score-from-ns",
        type=int,
        default=None,
        help="score frames from this Unix ns on (default: the recording's score_from_ns, e.g. a demo's warm-up end)",
    )
    p.add_argument(
        "--tracks-csv", default=None, metavar="FILE", help="also write the scored tracks as frame,id,x_m,y_m"
    )


def _session_and_prefix(args: argparse.Namespace) -> tuple[SessionSettings, str, str | None]:
    base = SessionSettings()
    prefix = DEFAULT_PREFIX
    agent_id = None
    if args.config:
        from user_agent.config import load_agent_config

        cfg = load_agent_config(args.config)
        base, prefix, agent_id = cfg.zenoh, cfg.agent.prefix, cfg.agent.id
    prefix = args.prefix or prefix
    Keys(prefix)
    return settings_from_args(args, base), prefix, args.agent_id or agent_id


def _client(args: argparse.Namespace) -> Any:
    from user_agent.client import AgentClient

    settings, prefix, agent_id = _session_and_prefix(args)
    agent = AgentClient(settings=settings, prefix=prefix, agent_id=agent_id)
    if settings.config_file and not agent.token_accepted():
        logger.warning(
            "the router did not take this agent's liveliness token %s: on a secure site an agent may speak only "
            "as its certificate's id (agent-ID.json5: --agent-id ID); PTZ requests under this id are refused too",
            agent.keys.agent(agent.agent_id),
        )
    return agent


def _dump(obj: Any) -> None:
    print(json.dumps(msgspec.to_builtins(obj), indent=2))


def _settled(agent: Any, wait_s: float, shutdown: Any = None) -> tuple[list[Any], list[Any]]:
    """(sensors, managers) once every live one has sent its status, or after ``wait_s``."""
    deadline = time.monotonic() + wait_s
    while True:
        sensors, managers = agent.sensors(timeout_s=0.5), agent.managers(timeout_s=0.3)
        done = all(v.status is not None for v in sensors if v.alive) and all(
            m.status is not None for m in managers if m.alive
        )
        if done or time.monotonic() >= deadline or (shutdown is not None and shutdown.is_set()):
            return sensors, managers
        time.sleep(0.2)


def _watch(args: argparse.Namespace) -> int:
    from user_agent.views import CLEAR_SCREEN, watch_screen

    shutdown = install_signal_handlers()
    tty = sys.stdout.isatty()
    with _client(args) as agent:
        end = time.monotonic() + args.duration if args.duration > 0 else float("inf")
        sensors, _ = _settled(agent, STATUS_WAIT_S, shutdown)
        last_sensors = time.monotonic()
        while True:
            if time.monotonic() - last_sensors > SENSORS_REFRESH_S:
                sensors, last_sensors = agent.sensors(timeout_s=1.0), time.monotonic()
            header = f"panostereo watch  {time.strftime('%H:%M:%S')}  prefix {agent.keys.prefix}"
            screen = watch_screen(agent.tracks(timeout_s=0), sensors, agent.managers(timeout_s=0.5), header)
            print((CLEAR_SCREEN if tty else "") + screen, flush=True)
            if args.once or time.monotonic() >= end or shutdown.sleep(args.interval):
                return 0


def _record(args: argparse.Namespace) -> int:
    from user_agent.record import McapSink, Recorder

    settings, prefix, agent_id = _session_and_prefix(args)
    meta: dict[str, str] = {"prefix": prefix}
    fps = args.fps
    if args.site:
        from common.site import load_site

        site = load_site(args.site)
        prefix = args.prefix or site.site.prefix
        meta.update(site=site.site.name, prefix=prefix, room_x_m=str(site.world.room_x_m))
        meta["room_y_m"] = str(site.world.room_y_m)
        if site.area is not None:  # where people can be: the plot is sized to it
            meta["area"] = json.dumps(site.area.polygon)
        if site.dataset is not None:
            fps = fps or site.dataset.fps
            meta.pop("room_x_m")
            meta.pop("room_y_m")
        fps = fps or site.site.fps
    epoch = args.epoch_ns if args.epoch_ns is not None else os.environ.get(EPOCH_ENV, "")
    if str(epoch).strip():
        try:
            meta["epoch_ns"] = str(int(epoch))
        except ValueError as err:
            raise ConfigError(f"environment {EPOCH_ENV}: expected integer Unix ns, got {epoch!r}") from err
    if fps:
        meta["fps"] = str(fps)
    exprs = _record_keys(Keys(prefix), args.keys)
    meta["keys"] = " ".join(exprs)
    shutdown = install_signal_handlers()
    with open_session(settings) as session:
        rec = Recorder(session, exprs, McapSink(args.out, meta))
        # Announce ourselves once subscribed, so a caller can wait for the recorder to be ready.
        token = session.liveliness().declare_token(Keys(prefix).agent(agent_id or f"recorder-{os.getpid()}"))
        end = time.monotonic() + args.duration if args.duration > 0 else float("inf")
        next_note = time.monotonic() + 5.0
        try:
            while time.monotonic() < end and not shutdown.sleep(min(0.2, max(0.0, end - time.monotonic()))):
                if time.monotonic() >= next_note:
                    next_note += 5.0
                    print(_recorder_note(rec.status(), rec.top_drops()), file=sys.stderr, flush=True)
        finally:
            token.undeclare()
            rec.stop()
    st = rec.status()
    print(f"recorded {st.written} samples into {args.out}; {_recorder_note(st, rec.top_drops())}", file=sys.stderr)
    return 0


def _record_keys(keys: Keys, patterns: list[str] | None) -> list[str]:
    """Full key expressions for ``--keys`` patterns (relative to ``{prefix}/@v1/`` unless they start with it)."""
    import zenoh

    if not patterns:
        return [keys.all]
    out = []
    for pat in patterns:
        full = pat if pat.startswith(keys.root + "/") else f"{keys.root}/{pat.strip('/')}"
        try:
            out.append(str(zenoh.KeyExpr(full)))
        except Exception as err:  # ZError: not a key expression
            raise ConfigError(f"--keys {pat!r}: not a key expression ({full}): {err}") from err
    return out


def _recorder_note(st: Any, top: list[tuple[str, int]]) -> str:
    lost = f"dropped {st.dropped} ({st.dropped_raw} raw sensor messages)" if st.dropped else "nothing dropped"
    most = "; most on " + ", ".join(f"{k or '(other keys)'} {n}" for k, n in top) if top else ""
    return f"recorder: {st.written} written, {lost}, {st.lag_s:.1f} s behind live (worst {st.max_lag_s:.1f} s){most}"


def _replay(args: argparse.Namespace) -> int:
    from user_agent.recording import read_metadata
    from user_agent.replay import replay

    read_metadata(args.input)  # a missing or corrupt file is an error before any network
    settings, _, _ = _session_and_prefix(args)
    shutdown = install_signal_handlers()
    with open_session(settings) as session:
        sent = replay(session, args.input, speed=args.speed, should_stop=shutdown.is_set, sleep=shutdown.sleep)
    print(f"replayed {sent} samples", file=sys.stderr)
    return 0


def _foxglove(args: argparse.Namespace) -> int:
    from user_agent.live import FoxgloveBridge

    settings, prefix, agent_id = _session_and_prefix(args)
    shutdown = install_signal_handlers()
    with open_session(settings) as session:
        bridge = FoxgloveBridge(session, Keys(prefix), args.host, args.port)
        token = session.liveliness().declare_token(Keys(prefix).agent(agent_id or f"foxglove-{os.getpid()}"))
        print(f"Foxglove: open ws://{args.host}:{bridge.port}", file=sys.stderr, flush=True)
        end = time.monotonic() + args.duration if args.duration > 0 else float("inf")
        try:
            bridge.refresh_sensors()
            while not shutdown.is_set() and time.monotonic() < end:
                bridge.pump(0.1)
        finally:
            token.undeclare()
            bridge.close()
    return 0


def _evaluate(args: argparse.Namespace) -> int:
    from user_agent.groundtruth import read_gt_csv
    from user_agent.recording import load_recording
    from user_agent.report import score_recording, write_tracks_csv

    rec = load_recording(args.input)
    scored = score_recording(
        rec,
        read_gt_csv(args.ground_truth),
        threshold_m=args.threshold,
        epoch_ns=args.epoch_ns,
        fps=args.fps,
        start_ns=args.score_from_ns,
    )
    out: dict[str, Any] = dict(scored.metrics.to_dict())
    out["tracks_published"] = scored.tracks_published
    if args.tracks_csv:
        out["tracks_csv_rows"] = write_tracks_csv(args.tracks_csv, scored.hypotheses)
    if args.json:
        print(json.dumps(out, indent=2))
    else:
        m = scored.metrics
        print(
            f"frames {m.frames}  objects {m.objects}  tracks {scored.tracks_published}\n"
            f"MOTA {m.mota:.3f}  MOTP {m.motp_m:.3f} m  IDF1 {m.idf1:.3f}  ID switches {m.id_switches}\n"
            f"precision {m.precision:.3f}  recall {m.recall:.3f}  FP {m.false_positives}  misses {m.misses}\n"
            f"error mean {m.mean_error_m:.3f} m  p90 {m.p90_error_m:.3f} m  (threshold {args.threshold} m)"
        )
    return 0


def run(args: argparse.Namespace) -> int:
    """Run the chosen subcommand."""
    action = args.action
    handler = _HANDLERS.get(action)
    if handler is not None:
        return handler(args)
    from user_agent.views import history_table, tracks_table

    if action in ("history", "view"):
        validate_id(args.track_id, "track id")  # before any network
    with _client(args) as agent:
        if action == "tracks":
            tracks = agent.tracks(timeout_s=args.timeout)
            _dump(tracks) if args.json else print(tracks_table(tracks))
        elif action == "history":
            path = agent.history(args.track_id, args.seconds, timeout_s=args.timeout)
            if not path:
                live = ", ".join(t.track_id for t in agent.tracks(timeout_s=1.0)) or "none"
                print(
                    f"no manager knows track {args.track_id!r} (or it has no state in the last {args.seconds:g} s); "
                    f"live tracks: {live}",
                    file=sys.stderr,
                )
                return 1
            _dump(path) if args.json else print(history_table(path))
        elif action == "sensors":
            sensors, managers = _settled(agent, STATUS_WAIT_S)
            if args.json:
                _dump(
                    [
                        {
                            "sensor_id": s.sensor_id,
                            "alive": s.alive,
                            "clock_offset_ns": s.clock_offset_ns,
                            "info": msgspec.to_builtins(s.info),
                            "status": msgspec.to_builtins(s.status),
                        }
                        for s in sensors
                    ]
                )
            else:
                from user_agent.views import watch_screen

                print(watch_screen(agent.tracks(timeout_s=TRACKS_WAIT_S), sensors, managers), end="")
        elif action == "view":
            return _view(args, agent)
    return 0


def _export(args: argparse.Namespace) -> int:
    from user_agent.export import export_rows, write_export
    from user_agent.recording import load_recording

    rec = load_recording(args.input)
    epoch = rec.meta_int("epoch_ns", -1)
    rows = export_rows(rec.tracksets, epoch_ns=epoch if epoch >= 0 else None)
    n = write_export(args.out, rows, args.format)
    tracks = len({tr.track_id for _, _, tr in rows})
    frames = len({k for k, _, _ in rows})
    print(f"wrote {n} rows ({tracks} tracks over {frames} frames) to {args.out} as {args.format}")
    if not rec.tracksets:
        print(f"{args.input}: the recording holds no TrackSet: nothing to export", file=sys.stderr)
    return 0


def _plot(args: argparse.Namespace) -> int:
    from user_agent.report import plot_recording

    out = plot_recording(
        args.input,
        args.out,
        args.ground_truth,
        title=args.title,
        threshold_m=args.threshold,
        epoch_ns=args.epoch_ns,
        fps=args.fps,
    )
    print(out)
    return 0


_HANDLERS: dict[str, Callable[[argparse.Namespace], int]] = {
    "watch": _watch,
    "record": _record,
    "replay": _replay,
    "evaluate": _evaluate,
    "foxglove": _foxglove,
    "plot": _plot,
    "export": _export,
}
"""The actions that need no agent session of their own (the others query through one)."""


def _view(args: argparse.Namespace, agent: Any) -> int:
    """Hold a view until Ctrl-C or ``--duration``, renewing its lease; release it on the way out."""
    if args.release:
        if not args.agent_id:
            raise ConfigError(
                "--release needs --agent-id: the id of the agent holding the view (a view also ends by itself when "
                "its agent exits)"
            )
        reply = agent.release_view(args.track_id, args.manager)
        _dump(reply)
        return 0 if reply.ok else 1
    shutdown = install_signal_handlers()
    reply = agent.request_view(args.track_id, args.priority, args.manager)
    _dump(reply)
    if not reply.ok:
        return 1
    print(
        f"holding {reply.sensor_id} on {args.track_id} as {agent.agent_id} (lease {reply.lease_s:g} s, renewed); "
        "Ctrl-C releases it",
        file=sys.stderr,
        flush=True,
    )
    end = time.monotonic() + args.duration if args.duration > 0 else float("inf")
    try:
        while time.monotonic() < end and not shutdown.sleep(min(0.5, max(0.0, end - time.monotonic()))):
            for renewed in agent.keep_views():
                if not renewed.ok:
                    _dump(renewed)
                    print(f"lost the view of {args.track_id}: {renewed.reason}", file=sys.stderr)
                    return 1
    finally:
        agent.release_all()
    return 0


def main(argv: list[str] | None = None) -> int:
    code = run_command("user-agent", "User-agent tools of a panostereo site.", configure, run, argv)
    if argv is None:
        exit_process(code)  # a process, not a call: no interpreter finalization under zenoh's threads
    return code
