"""Transport latency and throughput through a real ``panostereo router`` with typed Features.

Usage::

    python -m benchmarks.bench_transport [--messages N] [--blobs B] [--burst M]

Starts a router subprocess on a free loopback port, opens two client sessions in this process
(publisher and subscriber, both through the router), and measures:

* ``latency_us``: put → received and decoded by an :class:`~common.transport.Inbox` (``get``), one
  message in flight at a time: p50, p90, p99, max over ``messages`` messages after a warm-up;
* ``burst``: ``burst`` messages put back to back (DROP congestion control, as features are sent);
  how many arrived and the receive rate.

Prints one JSON object. Numbers vary ±30-50 % on a shared 2-core machine (docs/zenoh.md §4).
"""

from __future__ import annotations

import argparse
import json
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from common.codec import encode
from common.keys import Keys
from common.schema import Blob, Features
from common.session import SessionSettings, open_session
from common.transport import Inbox, TypedPublisher

REPO = Path(__file__).resolve().parent.parent


def start_router(log_path: Path, timeout_s: float = 15.0) -> tuple[subprocess.Popen[bytes], str]:
    """A router on tcp/127.0.0.1:0; returns the process and the endpoint it logged."""
    log = log_path.open("wb")
    proc = subprocess.Popen(
        [sys.executable, "-m", "panostereo", "router", "--listen", "tcp/127.0.0.1:0"],
        stdout=log,
        stderr=subprocess.STDOUT,
        cwd=REPO,
    )
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        m = re.search(r"listening on (tcp/127\.0\.0\.1:\d+)", log_path.read_text(errors="replace"))
        if m:
            return proc, m.group(1)
        if proc.poll() is not None:
            break
        time.sleep(0.02)
    proc.kill()
    raise RuntimeError(f"router did not start: {log_path.read_text(errors='replace')}")


def features(seq: int, blobs: int) -> Features:
    blob = Blob(
        local_id=1,
        bearing_rad=0.5,
        width_rad=0.1,
        top_elev_rad=0.2,
        bottom_elev_rad=-0.3,
        bbox_u_px=100.0,
        bbox_v_px=20.0,
        bbox_w_px=20.0,
        bbox_h_px=80.0,
        hist=[1.0 / 16] * 16,
    )
    return Features(sensor_id="bench", seq=seq, stamp_ns=time.time_ns(), frame_index=seq, blobs=[blob] * blobs)


def percentile(sorted_values: list[float], q: float) -> float:
    idx = min(len(sorted_values) - 1, max(0, round(q * (len(sorted_values) - 1))))
    return sorted_values[idx]


def run(messages: int, blobs: int, burst: int) -> dict[str, Any]:
    keys = Keys("bench")
    key = keys.sensor_features("bench")
    with tempfile.TemporaryDirectory() as tmp:
        router, endpoint = start_router(Path(tmp) / "router.log")
        try:
            settings = SessionSettings(mode="client", connect=[endpoint])
            with open_session(settings) as pub_s, open_session(settings) as sub_s:
                inbox = Inbox(sub_s, key, Features, capacity=max(1024, burst), drop_oldest=False)
                pub = TypedPublisher(pub_s, key, reliable_block=False)
                # Warm-up: until the subscription has propagated through the router.
                deadline = time.monotonic() + 10.0
                while inbox.get(timeout_s=0.05) is None:
                    pub.put(features(0, blobs))
                    if time.monotonic() > deadline:
                        raise RuntimeError("no message came through the router during warm-up")
                for i in range(50):
                    pub.put(features(i, blobs))
                    inbox.get(timeout_s=1.0)
                inbox.drain()

                lat_us: list[float] = []
                lost = 0
                for i in range(messages):
                    msg = features(i, blobs)
                    t0 = time.perf_counter_ns()
                    pub.put(msg)
                    r = inbox.get(timeout_s=1.0)
                    t1 = time.perf_counter_ns()
                    if r is None:
                        lost += 1
                        continue
                    lat_us.append((t1 - t0) / 1e3)
                lat_us.sort()

                inbox.drain()
                before = inbox.counters.received
                burst_t0 = time.monotonic()
                for i in range(burst):
                    pub.put(features(i, blobs))
                put_s = time.monotonic() - burst_t0
                quiet_since = time.monotonic()
                last = before
                while time.monotonic() - quiet_since < 0.5:  # until nothing new for 0.5 s
                    time.sleep(0.05)
                    now = inbox.counters.received
                    if now != last:
                        last, quiet_since = now, time.monotonic()
                received = inbox.counters.received - before
                recv_s = max(1e-9, quiet_since - burst_t0)
                pub.close()
                inbox.close()
        finally:
            router.terminate()
            router.wait(10)
    return {
        "benchmark": "transport",
        "path": "client -> python router -> client (loopback), typed Features via Inbox",
        "payload_bytes": len(encode(features(0, blobs))),
        "blobs_per_message": blobs,
        "latency_us": {
            "n": len(lat_us),
            "lost": lost,
            "p50": round(percentile(lat_us, 0.50), 1),
            "p90": round(percentile(lat_us, 0.90), 1),
            "p99": round(percentile(lat_us, 0.99), 1),
            "max": round(lat_us[-1], 1),
            "mean": round(statistics.fmean(lat_us), 1),
        },
        "burst": {
            "sent": burst,
            "received": received,
            "put_rate_per_s": round(burst / put_s),
            "receive_rate_per_s": round(received / recv_s),
        },
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m benchmarks.bench_transport", description=__doc__.split("\n\n")[0])
    p.add_argument("--messages", type=int, default=2000, help="latency samples")
    p.add_argument("--blobs", type=int, default=4, help="blobs per Features message")
    p.add_argument("--burst", type=int, default=5000, help="messages in the throughput burst")
    args = p.parse_args(argv)
    result = run(args.messages, args.blobs, args.burst)
    sys.stdout.write(json.dumps(result) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
