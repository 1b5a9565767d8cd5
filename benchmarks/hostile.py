"""Input valid on the wire but hostile in meaning (issue 15), and one client that floods a site with it.

Every message built here decodes (``common.codec.decode`` accepts it: the generator checks), so the
receivers' schema checks let all of it through; what it means is the attack:

* Features with 0 to 256 blobs of extreme but in-range numbers (bearings at +-pi, widths up to 2 pi,
  bounding boxes at +-1e5 px, 512-bin histograms), sightings of the sensor itself and of the others at
  up to 100 km, stamps from 1970, 2262, a few seconds off, or plausible (now, within the manager's skew);
* SensorInfo placing every camera at one spot (0.5, 0.5), surveyed, with odd models and body radii;
* PtzState, NodeStatus with extreme values; PTZ requests for tracks that do not exist, at top priority;
* each under a *fresh* sensor id (a new one per message, from a large pool) or a *real* one (the
  site's own ids), with the payload naming that id (an impostor) or another one (a liar).

Usage (the flood client; one JSON line on stdout when it stops)::

    python -m benchmarks.hostile flood --connect tcp/127.0.0.1:7447 --prefix pano \\
        --real pano1,pano2,pano3,ptz1 --manager mgr1 --real-share 0.0 --duration 20 [--seed 1]

``--real-share`` is the fraction of messages under the site's own ids (0: fresh ids only). It sends as
fast as one Python client can (a pool of pre-encoded payloads, keys formed per message) until
``--duration`` seconds have passed or SIGTERM. ``--max-size`` sends only the largest Features (256
blobs, ~200 KB, stamped now, the detector "ok") on the ``--real`` ids' keys: a valid camera flooding
its own key (``--zenoh-config`` gives the client that camera's certificate). ``--ptz-agent ID`` sends
only PTZ requests, as agent ID on its own key (``--zenoh-config``: its certificate), as fast as the
manager answers (``--ptz-window`` outstanding at once).
"""

from __future__ import annotations

import argparse
import json
import math
import random
import signal
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parent.parent
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from common.codec import decode, encode  # noqa: E402
from common.keys import Keys  # noqa: E402
from common.schema import (  # noqa: E402
    MAX_BLOBS,
    MAX_HIST_BINS,
    MAX_SIGHTINGS,
    Blob,
    Features,
    NodeStatus,
    PanoramicModel,
    PinholeModel,
    Pose,
    PtzRequest,
    PtzState,
    SensorInfo,
    Sighting,
)

__all__ = ["Payload", "hostile_pool", "main"]

STAMP_MAX = 2**63 - 1
"""The largest stamp the schema takes: 2262-04-11."""
FRESH_IDS = 100_000
"""Fresh sensor ids a flood draws from (``f{n}``): more than any manager or recorder keeps."""


@dataclass(frozen=True, slots=True)
class Payload:
    """One encoded hostile message and where it goes."""

    kind: str
    """``features``, ``info``, ``ptz_state`` or ``status`` (the key it is put on)."""
    sensor_id: str
    """The id its payload names."""
    data: bytes


def _blob(rng: random.Random, i: int) -> Blob:
    edge = rng.random() < 0.3
    return Blob(
        local_id=rng.choice([i, rng.randrange(2**63 - 1)]),
        bearing_rad=rng.choice([-math.pi, math.pi]) if edge else rng.uniform(-math.pi, math.pi),
        width_rad=rng.choice([0.0, 2 * math.pi]) if edge else rng.uniform(0.0, 0.6),
        top_elev_rad=rng.uniform(-math.pi / 2, math.pi / 2),
        bottom_elev_rad=rng.uniform(-math.pi / 2, math.pi / 2),
        bbox_u_px=rng.choice([-1e5, 1e5]) if edge else rng.uniform(0, 2000),
        bbox_v_px=rng.uniform(-1e5, 1e5),
        bbox_w_px=rng.choice([0.0, 1e5]) if edge else rng.uniform(1, 200),
        bbox_h_px=rng.uniform(0.0, 1e5),
        hist=[rng.random() for _ in range(MAX_HIST_BINS if rng.random() < 0.01 else rng.choice([0, 8, 16]))],
        changed_frac=rng.random(),
        feet_visible=rng.random() < 0.5,
        confidence=rng.choice([0.0, 1.0, rng.random()]),
    )


def _sighting(rng: random.Random, own: str, others: Sequence[str]) -> Sighting:
    return Sighting(
        target_id=own if rng.random() < 0.5 else rng.choice([*others, ""]),  # sighting itself, half the time
        left_rad=rng.uniform(-math.pi, math.pi),
        right_rad=rng.uniform(-math.pi, math.pi),
        alpha_rad=rng.uniform(0.0, 2 * math.pi),
        bearing_rad=rng.uniform(-math.pi, math.pi),
        distance_m=rng.choice([0.0, 1e5, rng.uniform(0.1, 20.0)]),
        body_radius_m=rng.choice([0.0, 1e5, 0.18]),
    )


def _stamp(rng: random.Random, now_ns: int) -> int:
    r = rng.random()
    if r < 0.15:
        return rng.randrange(0, 10**9)  # 1970
    if r < 0.3:
        return STAMP_MAX - rng.randrange(0, 10**9)  # 2262
    if r < 0.45:
        return now_ns + rng.choice([-1, 1]) * rng.randrange(3 * 10**9, 60 * 10**9)  # seconds off
    return now_ns + rng.randrange(-(10**9), 10**9)  # plausible: within any sane skew


def _features(rng: random.Random, sid: str, others: Sequence[str], now_ns: int) -> Features:
    r = rng.random()
    n = MAX_BLOBS if r < 0.03 else (rng.randint(9, 40) if r < 0.15 else rng.randint(0, 8))
    return Features(
        sensor_id=sid,
        seq=rng.choice([0, rng.randrange(2**63 - 1), 2**63 - 1]),
        stamp_ns=_stamp(rng, now_ns),
        frame_index=rng.randrange(2**63 - 1),
        blobs=[_blob(rng, i) for i in range(n)],
        sightings=[_sighting(rng, sid, others) for _ in range(rng.choice([0, 1, 3, MAX_SIGHTINGS]))],
        processing_ms=rng.choice([0.0, 1e9]),
        state=rng.choice(["ok", "ok", "learning", "moving"]),
    )


def _info(rng: random.Random, sid: str, now_ns: int) -> SensorInfo:
    model: PanoramicModel | PinholeModel
    if rng.random() < 0.5:
        model = PanoramicModel(
            width_px=rng.choice([8, 100_000, 1080]),
            height_px=rng.choice([8, 162]),
            f_v_px=rng.choice([1e-6, 1e6]),
            v0_px=rng.choice([-1e5, 1e5, 93.0]),
        )
    else:
        model = PinholeModel(width_px=640, height_px=480, k=[rng.uniform(-1e9, 1e9) for _ in range(9)])
    return SensorInfo(
        sensor_id=sid,
        seq=rng.randrange(2**63 - 1),
        stamp_ns=_stamp(rng, now_ns),
        kind=rng.choice(["panoramic", "ptz", "pinhole"]),
        model=model,
        pose=Pose(x_m=0.5, y_m=0.5, z_m=rng.choice([0.0, 1.1]), yaw_rad=0.0),  # every camera at one spot
        pose_source="surveyed",
        mobile=rng.random() < 0.3,
        body_radius_m=rng.choice([0.0, 0.18, 1e5]),
        bearing_sigma_rad=rng.choice([0.0, 1.0, 0.0035]),
    )


def _ptz_state(rng: random.Random, sid: str, now_ns: int) -> PtzState:
    return PtzState(
        sensor_id=sid,
        seq=rng.randrange(2**63 - 1),
        stamp_ns=_stamp(rng, now_ns),
        pan_rad=rng.uniform(-math.pi, math.pi),
        tilt_rad=rng.choice([-math.pi / 2, math.pi / 2]),
        zoom=rng.choice([0.1, 1000.0]),
        moving=True,
    )


def _status(rng: random.Random, sid: str, now_ns: int) -> NodeStatus:
    return NodeStatus(
        sensor_id=sid,
        seq=rng.randrange(2**63 - 1),
        stamp_ns=_stamp(rng, now_ns),
        fps=1e6,
        frames=2**63 - 1,
        dropped_frames=2**63 - 1,
        processing_ms=1e9,
        clock_offset_ns=rng.choice([-(2**62), 2**62]),
        clock_uncertainty_ns=2**63 - 1,
        clock_source="ntp",
        decode_errors=2**63 - 1,
        source_state=rng.choice(["ok", "failed", "reconnecting"]),
        message="x" * 256,
    )


KINDS: tuple[tuple[str, float], ...] = (("features", 0.8), ("info", 0.08), ("ptz_state", 0.06), ("status", 0.06))
"""The mix of a flood (fraction of messages per kind)."""


def hostile_pool(real: Sequence[str], size: int, seed: int, now_ns: int | None = None) -> list[Payload]:
    """``size`` pre-encoded hostile messages naming the ``real`` ids (and, one in ten, a liar's fresh id).

    Raises:
        AssertionError: a generated message does not decode (the generator's own check: all must be valid).
    """
    rng = random.Random(seed)
    now = time.time_ns() if now_ns is None else now_ns
    names = list(real) or ["f0"]
    out: list[Payload] = []
    types = {"features": Features, "info": SensorInfo, "ptz_state": PtzState, "status": NodeStatus}
    for _ in range(size):
        kind = rng.choices([k for k, _ in KINDS], [w for _, w in KINDS])[0]
        sid = rng.choice(names) if rng.random() < 0.9 else f"liar{rng.randrange(1000)}"
        msg: Any
        if kind == "features":
            msg = _features(rng, sid, names, now)
        elif kind == "info":
            msg = _info(rng, sid, now)
        elif kind == "ptz_state":
            msg = _ptz_state(rng, sid, now)
        else:
            msg = _status(rng, sid, now)
        data = encode(msg)
        decode(data, types[kind])  # valid on the wire, or this is not the attack meant here
        out.append(Payload(kind, sid, data))
    return out


def max_size_features(sid: str, now_ns: int, seed: int = 0) -> bytes:
    """The largest Features a camera may send that still looks like a frame: 256 blobs with 64-bin colours."""
    rng = random.Random(seed)
    blobs = [
        Blob(
            local_id=i,
            bearing_rad=rng.uniform(-math.pi, math.pi),
            width_rad=rng.uniform(0.02, 0.3),
            top_elev_rad=rng.uniform(0.0, 0.5),
            bottom_elev_rad=rng.uniform(-0.8, -0.1),
            bbox_u_px=rng.uniform(0, 1000),
            bbox_v_px=rng.uniform(0, 100),
            bbox_w_px=rng.uniform(5, 100),
            bbox_h_px=rng.uniform(10, 100),
            hist=[rng.random() / 64 for _ in range(64)],
            changed_frac=rng.random(),
            confidence=rng.random(),
        )
        for i in range(MAX_BLOBS)
    ]
    msg = Features(sensor_id=sid, seq=rng.randrange(2**62), stamp_ns=now_ns, frame_index=0, blobs=blobs)
    data = encode(msg)
    decode(data, Features)
    return data


def _key(keys: Keys, kind: str, sid: str) -> str:
    if kind == "features":
        return keys.sensor_features(sid)
    if kind == "info":
        return keys.sensor_info(sid)
    if kind == "ptz_state":
        return keys.sensor_ptz_state(sid)
    return keys.sensor_status(sid)


def flood(args: argparse.Namespace) -> dict[str, Any]:
    """Put hostile messages as fast as one client can for ``args.duration`` s; return what was sent."""
    import zenoh

    from common.session import SessionSettings, open_session

    keys = Keys(args.prefix)
    real = [s for s in args.real.split(",") if s]
    rng = random.Random(args.seed)
    # Pools are re-encoded every few seconds so that "plausible" stamps stay near the clock.
    pool = hostile_pool(real, args.pool, args.seed)
    pool_t = time.monotonic()
    stop = [False]
    signal.signal(signal.SIGTERM, lambda *_: stop.__setitem__(0, True))
    sent = {"fresh": 0, "real": 0, "ptz_requests": 0}
    cc = zenoh.CongestionControl.BLOCK if args.block else zenoh.CongestionControl.DROP
    settings = SessionSettings(mode="client", connect=[args.connect], config_file=args.zenoh_config or "")
    with open_session(settings) as s:
        print(json.dumps({"flooding": True}), flush=True)
        t0 = time.monotonic()
        i = 0
        if args.max_size:
            return _flood_max_size(s, keys, real, cc, t0, stop, args)
        if args.ptz_agent:
            return _flood_ptz(s, keys, args, t0, stop)
        while not stop[0] and time.monotonic() - t0 < args.duration:
            for p in pool:
                if args.rate > 0 and i >= args.rate * (time.monotonic() - t0):
                    time.sleep(0.001)  # --rate: no faster than that
                if rng.random() < args.real_share and real:
                    sid = p.sensor_id if p.sensor_id in real else rng.choice(real)
                    sent["real"] += 1
                else:
                    sid = f"f{rng.randrange(FRESH_IDS)}"
                    sent["fresh"] += 1
                s.put(_key(keys, p.kind, sid), p.data, congestion_control=cc)
                i += 1
                if args.manager and i % 2000 == 0:  # a PTZ request for a track that does not exist, top priority
                    req = PtzRequest(agent_id="mallory", seq=i, stamp_ns=time.time_ns(), action="acquire",
                                     track_id=f"{args.manager}-{rng.randrange(10**9)}", priority=1000)  # fmt: skip
                    s.get(keys.ptz_request(args.manager, "mallory"), lambda _r: None, payload=encode(req), timeout=1.0)
                    sent["ptz_requests"] += 1
            if time.monotonic() - pool_t > 5.0:
                pool, pool_t = hostile_pool(real, args.pool, rng.randrange(2**31)), time.monotonic()
        elapsed = time.monotonic() - t0
    total = sent["fresh"] + sent["real"]
    return {"sent": total, **sent, "seconds": round(elapsed, 2), "rate_hz": round(total / max(elapsed, 1e-9))}


def _flood_max_size(
    s: Any, keys: Keys, real: list[str], cc: Any, t0: float, stop: list[bool], args: argparse.Namespace
) -> dict[str, Any]:
    """Only the largest Features, on the ``real`` ids' keys, restamped every 0.1 s so they stay plausible."""
    sent, i = 0, 0
    frames: list[tuple[str, bytes]] = []
    made = -1.0
    while not stop[0] and time.monotonic() - t0 < args.duration:
        if time.monotonic() - made > 0.1:
            now = time.time_ns()
            frames = [
                (keys.sensor_features(sid), max_size_features(sid, now, args.seed + k)) for k, sid in enumerate(real)
            ]
            made = time.monotonic()
        key, data = frames[i % len(frames)]
        if args.rate > 0 and sent >= args.rate * (time.monotonic() - t0):
            time.sleep(0.001)
            continue
        s.put(key, data, congestion_control=cc)
        sent += 1
        i += 1
    elapsed = time.monotonic() - t0
    return {"sent": sent, "real": sent, "bytes": len(frames[0][1]) if frames else 0, "seconds": round(elapsed, 2),
            "rate_hz": round(sent / max(elapsed, 1e-9))}  # fmt: skip


def _flood_ptz(s: Any, keys: Keys, args: argparse.Namespace, t0: float, stop: list[bool]) -> dict[str, Any]:
    """PTZ requests as agent ``args.ptz_agent`` on its own key, ``args.ptz_window`` outstanding at once."""
    import threading

    import zenoh

    window = threading.Semaphore(args.ptz_window)
    sent = 0
    key = keys.ptz_request(args.manager, args.ptz_agent)
    while not stop[0] and time.monotonic() - t0 < args.duration:
        if not window.acquire(timeout=1.0):
            continue
        req = PtzRequest(agent_id=args.ptz_agent, seq=sent, stamp_ns=time.time_ns(), action="acquire",
                         track_id=f"{args.manager}-{sent % 1000 + 1}", priority=1000)  # fmt: skip
        # The slot is freed when the query completes (its reply came, or it timed out).
        s.get(key, zenoh.handlers.Callback(lambda _r: None, window.release), payload=encode(req), timeout=2.0)
        sent += 1
    elapsed = time.monotonic() - t0
    return {
        "sent": sent,
        "ptz_requests": sent,
        "seconds": round(elapsed, 2),
        "rate_hz": round(sent / max(elapsed, 1e-9)),
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="benchmarks.hostile", description=__doc__.split("\n\n")[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    f = sub.add_parser("flood", help="flood a site with schema-valid hostile messages")
    f.add_argument("--connect", required=True, help="the site's router endpoint")
    f.add_argument("--prefix", default="pano")
    f.add_argument("--real", default="", help="the site's sensor ids, comma separated")
    f.add_argument("--real-share", type=float, default=0.0, help="fraction of messages under the site's own ids")
    f.add_argument("--manager", default="", help="manager id to send PTZ requests for unknown tracks to")
    f.add_argument("--duration", type=float, default=10.0)
    f.add_argument("--seed", type=int, default=1)
    f.add_argument("--pool", type=int, default=600, help="distinct hostile messages cycled through")
    f.add_argument("--block", action="store_true", help="BLOCK congestion control (default DROP)")
    f.add_argument("--rate", type=float, default=0.0, help="messages per second at most (0: as fast as it can)")
    f.add_argument("--zenoh-config", default="", help="zenoh config of the client (a certificate of the site)")
    f.add_argument("--max-size", action="store_true", help="only the largest Features, on the --real ids' keys")
    f.add_argument("--ptz-agent", default="", help="only PTZ requests, as this agent (needs --manager)")
    f.add_argument("--ptz-window", type=int, default=64, help="PTZ requests outstanding at once")
    args = p.parse_args(argv)
    print(json.dumps(flood(args)), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
