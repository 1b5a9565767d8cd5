"""Rendering benchmark: frames per second of one simulated camera on one core.

Usage::

    python -m benchmarks.bench_render [--site deploy/sites/demo.toml] [--camera pano3] [--frames 150]
                                      [--ptz-camera ptz1] [--warmup 5]

Renders ``frames`` consecutive frames at the site's fps (world time advances
1/fps per frame, so people move, the cached room background is reused for a
static camera) and prints one JSON object:

* ``fps``: panoramic frames per second (wall clock), full pipeline of a raw
  768 x 576 annular frame (cast the panorama, paint people and bodies, light,
  warp through the lens model, sensor noise) -- goal >= 30 on one core;
  ``cpu_fps``: the same from the process's CPU time, which does not drop when
  other processes share the core (the honest per-core figure on a busy machine);
* ``ms_p50`` / ``ms_p90``: per-frame times;
* ``mobile_fps``: the same for a mobile robot that is driving (room background
  re-cast every frame), if the site has one;
* ``ptz_fps``: the PTZ camera's frames per second at its configured pan/tilt/zoom.

Pins itself to one CPU (``os.sched_setaffinity``) and limits OpenCV to one
thread, so the figure is per core.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np

from common.site import load_site
from sim.render.cameras import PanoramicRenderer, PtzRenderer
from sim.world import World

REPO = Path(__file__).resolve().parents[1]


def _time_frames(render: Callable[[float], object], fps: float, frames: int, warmup: int) -> tuple[list[float], float]:
    """Wall-clock seconds per frame, and the CPU seconds all frames took."""
    for k in range(warmup):
        render(k / fps)
    times = []
    cpu0 = time.process_time()
    for k in range(frames):
        t0 = time.perf_counter()
        render((warmup + k) / fps)
        times.append(time.perf_counter() - t0)
    return times, time.process_time() - cpu0


def _summary(timed: tuple[list[float], float]) -> dict[str, float]:
    times, cpu_s = timed
    ordered = sorted(times)
    return {
        "fps": round(len(times) / sum(times), 1),
        "cpu_fps": round(len(times) / max(cpu_s, 1e-9), 1),
        "ms_p50": round(1000 * statistics.median(times), 2),
        "ms_p90": round(1000 * ordered[int(0.9 * (len(ordered) - 1))], 2),
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="bench_render", description=__doc__.splitlines()[0])
    p.add_argument("--site", default=str(REPO / "deploy" / "sites" / "demo.toml"))
    p.add_argument("--camera", default="pano3", help="panoramic camera to time (static: background cached)")
    p.add_argument("--ptz-camera", default="ptz1", help="PTZ camera to time ('' to skip)")
    p.add_argument("--frames", type=int, default=150)
    p.add_argument("--warmup", type=int, default=5)
    args = p.parse_args(argv)

    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
    cv2.setNumThreads(1)
    site = load_site(args.site)
    fps = site.site.fps
    world = World.from_site(site)
    rng = np.random.default_rng(0)
    cam = site.camera_by_id(args.camera)
    pano = PanoramicRenderer(world, cam)
    out: dict[str, object] = {
        "site": site.site.name,
        "camera": cam.id,
        "image_size": list(cam.image_size),
        "pano_size": list(cam.pano_size),
        "people": site.world.people,
        "frames": args.frames,
        **_summary(_time_frames(lambda t: pano.render(t, rng), fps, args.frames, args.warmup)),
    }
    mobile = next((c for c in site.camera if c.mobile and c.kind == "panoramic"), None)
    if mobile is not None:
        moving = World.from_site(site)
        moving.set_goal(mobile.id, site.world.room_x_m - mobile.x_m, site.world.room_y_m - mobile.y_m, 0.0)
        rend = PanoramicRenderer(moving, mobile)
        timed = _time_frames(lambda t: rend.render(t, rng), fps, max(args.frames // 3, 10), args.warmup)
        out["mobile_camera"] = mobile.id
        out["mobile_fps"] = _summary(timed)["fps"]
        out["mobile_cpu_fps"] = _summary(timed)["cpu_fps"]
    if args.ptz_camera:
        ptz_cam = site.camera_by_id(args.ptz_camera)
        ptz = PtzRenderer(world, ptz_cam)
        pan, tilt = math.radians(ptz_cam.pan_deg), math.radians(ptz_cam.tilt_deg)
        timed = _time_frames(lambda t: ptz.render(t, pan, tilt, ptz_cam.zoom, rng), fps, max(args.frames // 3, 10), 2)
        out["ptz_camera"] = ptz_cam.id
        out["ptz_fps"] = _summary(timed)["fps"]
        out["ptz_cpu_fps"] = _summary(timed)["cpu_fps"]
    sys.stdout.write(json.dumps(out) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
