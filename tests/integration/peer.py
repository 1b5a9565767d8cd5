"""A small client process for the transport and session integration tests (run with sys.executable).

    python tests/integration/peer.py sensor  --connect tcp/127.0.0.1:PORT --prefix P --id cam1
    python tests/integration/peer.py manager --connect tcp/127.0.0.1:PORT --prefix P --id mgr1

``sensor``: liveliness token ``sensor/{id}``; Features on ``sensor/{id}/features`` every ``--period-s``;
a queryable on ``sensor/{id}/info`` answering SensorInfo; a FIFO inbox of PtzCommand on ``sensor/{id}/ptz``,
each answered with a PtzState on ``sensor/{id}/ptz/state``.

``manager``: liveliness token ``manager/{id}``; watches sensor liveliness; for each sensor that appears it
queries its info, reads its Features through a ring inbox and sends one PtzCommand; reports PtzStates.

Both write one JSON object per line on stdout (``{"event": ...}``) for the test to read, and exit 0 on
SIGINT/SIGTERM after closing their session.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from common.cli import run_main
from common.codec import decode, encode
from common.keys import Keys
from common.schema import Features, PanoramicModel, PtzCommand, PtzState, SensorInfo
from common.session import MSGPACK, SessionSettings, install_signal_handlers, open_session
from common.transport import Inbox, TypedPublisher


def emit(event: str, **fields: Any) -> None:
    sys.stdout.write(json.dumps({"event": event, **fields}) + "\n")
    sys.stdout.flush()


def run_sensor(session: Any, keys: Keys, ident: str, period_s: float, shutdown: Any) -> None:
    info = SensorInfo(
        sensor_id=ident,
        seq=0,
        stamp_ns=time.time_ns(),
        kind="panoramic",
        model=PanoramicModel(width_px=1080, height_px=162, f_v_px=170.0, v0_px=81.0),
    )

    def on_query(query: Any) -> None:
        with query:  # always finalise (docs/zenoh.md §1.4)
            query.reply(keys.sensor_info(ident), encode(info), encoding=MSGPACK)

    queryable = session.declare_queryable(keys.sensor_info(ident), on_query, complete=True)
    features = TypedPublisher(session, keys.sensor_features(ident))
    states = TypedPublisher(session, keys.sensor_ptz_state(ident), reliable_block=True)
    commands = Inbox(session, keys.sensor_ptz(ident), PtzCommand, capacity=16, drop_oldest=False)
    token = session.liveliness().declare_token(keys.sensor(ident))
    emit("ready", role="sensor", id=ident)
    seq = 0
    try:
        while not shutdown.sleep(period_s):
            features.put(Features(sensor_id=ident, seq=seq, stamp_ns=time.time_ns(), frame_index=seq))
            seq += 1
            for r in commands.drain():
                cmd = r.msg
                emit("command", pan_rad=cmd.pan_rad, seq=cmd.seq)
                states.put(
                    PtzState(
                        sensor_id=ident,
                        seq=cmd.seq,
                        stamp_ns=time.time_ns(),
                        pan_rad=cmd.pan_rad,
                        tilt_rad=cmd.tilt_rad,
                        zoom=cmd.zoom,
                    )
                )
    finally:
        token.undeclare()
        commands.close()
        features.close()
        states.close()
        queryable.undeclare()
        emit("stopped", sent=seq)


def run_manager(session: Any, keys: Keys, ident: str, shutdown: Any) -> None:
    token = session.liveliness().declare_token(keys.manager(ident))
    feats = Inbox(session, keys.all_features, Features, capacity=64, drop_oldest=True)
    states = Inbox(session, keys.all_ptz_state, PtzState, capacity=64, drop_oldest=False)
    presence: list[tuple[str, bool]] = []

    def on_token(sample: Any) -> None:  # only enqueue: the work happens on the main thread
        import zenoh

        presence.append((str(sample.key_expr), sample.kind == zenoh.SampleKind.PUT))

    watcher = session.liveliness().declare_subscriber(keys.all_sensors, on_token, history=True)
    commander = TypedPublisher(session, keys.sensor_ptz("cam1"), reliable_block=True)
    emit("ready", role="manager", id=ident)
    seen_features: set[str] = set()
    cmd_seq = 0
    try:
        while not shutdown.sleep(0.02):
            while presence:
                key, alive = presence.pop(0)
                sensor = keys.parse(key).ident
                if not alive:
                    emit("sensor_gone", id=sensor)
                    continue
                emit("sensor_alive", id=sensor)
                for reply in session.get(keys.sensor_info(sensor), timeout=5.0):
                    if reply.ok is not None:
                        got = decode(reply.ok.payload.to_bytes(), SensorInfo)
                        emit("info", id=got.sensor_id, width_px=got.model.width_px, key=str(reply.ok.key_expr))
            for r in feats.drain():
                if r.msg.sensor_id not in seen_features:
                    seen_features.add(r.msg.sensor_id)
                    emit("features", id=r.msg.sensor_id, seq=r.msg.seq, key=r.key)
            if seen_features and cmd_seq < 50:
                cmd_seq += 1  # re-sent until the sensor answers: its inbox may not be matched yet
                commander.put(
                    PtzCommand(
                        manager_id=ident,
                        seq=cmd_seq,
                        stamp_ns=time.time_ns(),
                        sensor_id="cam1",
                        pan_rad=0.5,
                        tilt_rad=0.1,
                    )
                )
            for st in states.drain():
                emit("ptz_state", id=st.msg.sensor_id, pan_rad=st.msg.pan_rad, seq=st.msg.seq)
                cmd_seq = 50
    finally:
        watcher.undeclare()
        token.undeclare()
        feats.close()
        states.close()
        commander.close()
        emit("stopped", decode_errors=feats.counters.decode_errors)


def main() -> int:
    p = argparse.ArgumentParser()
    p.add_argument("role", choices=["sensor", "manager"])
    p.add_argument("--connect", required=True)
    p.add_argument("--prefix", default="pano")
    p.add_argument("--id", required=True)
    p.add_argument("--period-s", type=float, default=0.02)
    p.add_argument("--connect-timeout-ms", type=int, default=10_000)
    args = p.parse_args()
    shutdown = install_signal_handlers()
    keys = Keys(args.prefix)
    emit("opening", connect=args.connect)
    settings = SessionSettings(mode="client", connect=[args.connect], connect_timeout_ms=args.connect_timeout_ms)

    def body() -> int:
        with open_session(settings) as session:
            emit("opened")
            if args.role == "sensor":
                run_sensor(session, keys, args.id, args.period_s, shutdown)
            else:
                run_manager(session, keys, args.id, shutdown)
        return 0

    return run_main(body, f"peer {args.role}")


if __name__ == "__main__":
    sys.exit(main())
