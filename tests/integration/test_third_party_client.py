"""A third-party client that knows only zenoh, msgpack and the README's key table.

It joins a running site (a Wildtrack dataset site run by ``panostereo demo``:
real camera geometry, detection files, the real manager), reads tracks from
``pano/@v1/tracks``, queries a track's latest state and its history, lists the
sensors by liveliness and queries their info. Nothing from the project is
imported on the client side: keys are written as the README documents them.
"""

from __future__ import annotations

import importlib.util
import json
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import msgpack
import pytest
import zenoh

from panostereo.datasets.wildtrack import import_wildtrack
from tests.support import REPO, free_port, skip_or_fail, wait_for

pytestmark = pytest.mark.integration

DATASET = REPO.parent / "shared" / "datasets" / "wildtrack"
CAMERAS = ("cvlab1", "cvlab2", "cvlab3", "idiap1")


def _site(tmp: Path) -> Path:
    """An imported Wildtrack site reduced to four cameras (fewer processes on a 2-core machine)."""
    res = import_wildtrack(DATASET, tmp / "wt", max_frames=80)
    text = res.site.read_text()
    head = text.split("[[process]]")[0]
    procs = (
        "".join(f'[[process]]\nname = "{c}"\ncommand = "node"\nconfig = "nodes/{c}.toml"\n\n' for c in CAMERAS)
        + '[[process]]\nname = "manager"\ncommand = "manager"\nconfig = "nodes/manager.toml"\n'
    )
    site = tmp / "wt" / "site4.toml"
    site.write_text(head + procs)
    return site


def _session(port: int) -> Any:
    conf = zenoh.Config()
    conf.insert_json5("mode", '"client"')
    conf.insert_json5("connect/endpoints", json.dumps([f"tcp/127.0.0.1:{port}"]))
    conf.insert_json5("connect/timeout_ms", "30000")
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("listen/endpoints", "[]")
    return zenoh.open(conf)


def _get(s: Any, selector: str) -> list[dict[str, Any]]:
    replies = s.get(selector, timeout=3.0, consolidation=zenoh.ConsolidationMode.NONE)
    return [msgpack.unpackb(r.ok.payload.to_bytes()) for r in replies if r.ok is not None]


def test_plain_zenoh_msgpack_client_reads_tracks_and_queries_history(tmp_path: Path) -> None:
    for mod in ("sensor_node.node", "resource_manager.node", "resource_manager.cli"):
        if importlib.util.find_spec(mod) is None:
            skip_or_fail(f"{mod} is not there yet")
    if not (DATASET / "annotations_positions").is_dir():
        skip_or_fail(f"Wildtrack annotations not found at {DATASET}")
    site = _site(tmp_path)
    port = free_port()
    out = tmp_path / "run"
    demo = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "panostereo",
            "demo",
            "--site",
            str(site),
            "--duration",
            "30",
            "--out",
            str(out),
            "--listen",
            f"tcp/127.0.0.1:{port}",
            "--no-view",
        ],
        stdout=(tmp_path / "demo.log").open("w"),
        stderr=subprocess.STDOUT,
    )
    try:
        with _session(port) as s:
            sub = s.declare_subscriber("pano/@v1/tracks", zenoh.handlers.RingChannel(4))

            def a_trackset_with_tracks() -> dict[str, Any] | None:
                sample = sub.try_recv()
                if sample is None:
                    assert demo.poll() is None, "demo ended early"
                    return None
                ts = msgpack.unpackb(sample.payload.to_bytes())
                return ts if ts["tracks"] else None

            ts = wait_for(a_trackset_with_tracks, 60, "a TrackSet with tracks")
            assert ts["type"] == "pano.TrackSet" and isinstance(ts["stamp_ns"], int)
            track = ts["tracks"][0]
            assert track["type"] == "pano.Track"
            tid = track["track_id"]
            assert tid.startswith(ts["manager_id"] + "-")
            assert {"x_m", "y_m", "height_m", "vx_mps", "vy_mps", "state", "sensors", "predicted_error_m"} <= set(track)

            (latest,) = wait_for(lambda: _get(s, f"pano/@v1/track/{tid}"), 10, "latest state of the track")
            assert latest["track_id"] == tid and latest["stamp_ns"] >= track["stamp_ns"]

            time.sleep(2.0)  # the track lives on: its history grows
            path = wait_for(lambda: [p for p in [_get(s, f"pano/@v1/track/{tid}?history=60")] if len(p) >= 3], 10,
                            "a history of at least 3 states")[0]  # fmt: skip
            stamps = [p["stamp_ns"] for p in path]
            assert stamps == sorted(stamps) and all(p["track_id"] == tid for p in path)
            assert stamps[-1] - stamps[0] > 1e9

            alive = [str(r.ok.key_expr) for r in s.liveliness().get("pano/@v1/sensor/*", timeout=2.0) if r.ok]
            assert sorted(k.rsplit("/", 1)[1] for k in alive) == sorted(CAMERAS)
            infos = _get(s, "pano/@v1/sensor/*/info")
            assert {i["sensor_id"] for i in infos} == set(CAMERAS)
            assert all(i["model"]["type"] == "pano.PinholeModel" for i in infos)
            sub.undeclare()
        demo.send_signal(signal.SIGINT)  # seen what it needs: the demo stops as on Ctrl-C and still reports
        demo.wait(timeout=120)
    finally:
        if demo.poll() is None:
            demo.terminate()
            demo.wait(30)
    assert demo.returncode == 0, (tmp_path / "demo.log").read_text()[-4000:]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["cameras"]["started"] == summary["cameras"]["publishing"] == len(CAMERAS)
    assert summary["interrupted"] and summary["frames"] > 0 and summary["tracks_published"] > 0
    assert isinstance(summary["mota"], float)
