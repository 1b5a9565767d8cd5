"""Sensor-node pipeline throughput: annular 768x576 frame in -> encoded Features out, on one core.

Usage::

    python -m benchmarks.bench_pipeline [--site deploy/sites/demo.toml] [--camera pano1] [--frames 150] [--passes 3]

Renders ``frames`` annular frames of a simulated camera once (people walking,
other robots in view), then times on one core (``cv2.setNumThreads(1)``):

* **pipeline** -- :class:`sensor_node.pipeline.ImagePipeline` (unwarp, grey,
  background model with frame differencing and ghost checks, blobs, sightings,
  head extraction, annotation with colour histograms, 2D tracks) plus
  ``common.codec.encode`` of the Features message;
* **floor** -- the least any such pipeline does with OpenCV on the same frames:
  ``cvtColor`` of the annular frame to grey (connected components need one
  channel; converting before the remap is the cheaper order) + ``remap``
  (same fixed-point maps) + ``absdiff`` against a background + ``threshold``
  + ``connectedComponentsWithStats``. The ratio is taken against this, the
  faster floor; the colour-remap floor (remap BGR, then grey) is reported too.

Both run over the same frames after one untimed warm pass (the background
model is learnt), in interleaved passes; the best pass of each counts. Times
are the thread's CPU time (``time.thread_time``) -- the cost on one core even
when the machine is shared; wall-clock figures are reported beside them.
Prints one JSON object with frames/s of each, their ratio, the goal
(>= 300 frames/s and >= 50 % of the floor), the median blobs, sightings and
Features bytes per frame, and the load average.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from pathlib import Path
from typing import Any

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import cv2
import numpy as np

from common.codec import encode
from common.site import load_site
from sensor_node.config import BodySpec, PipelineSettings
from sensor_node.features import PanoramicGeometry
from sensor_node.pipeline import ImagePipeline
from sensor_node.unwarp import Unwarper
from sim.render.cameras import PanoramicRenderer
from sim.world import World

REPO = Path(__file__).resolve().parent.parent

STAMP_FPS = 15.0
"""Frame k is stamped k / STAMP_FPS s (the pipeline's warm-up spans seconds of stamps)."""


def _frames(site_path: Path, camera: str, n: int, t0_s: float) -> tuple[list[Any], Any, Any, list[BodySpec]]:
    site = load_site(site_path)
    world = World.from_site(site)
    renderer = PanoramicRenderer(world, site.camera_by_id(camera))
    rng = np.random.default_rng(1)
    frames = [renderer.render(t0_s + k / site.site.fps, rng) for k in range(n)]
    bodies = [
        BodySpec(id=c.id, band_rgb=list(c.band_rgb), radius_m=c.body_radius_m, height_m=c.body_height_m)
        for c in site.camera
        if c.id != camera and c.body_radius_m > 0
    ]
    annular, cyl = renderer.models
    return frames, annular, cyl, bodies


def _floor_pass(frames: list[Any], unwarper: Unwarper, bg: Any, grey_first: bool) -> tuple[float, float]:
    """Seconds per frame of remap + absdiff + threshold + connected components over the frames.

    ``grey_first``: convert the annular frame to grey and remap one channel (the cheaper order, and
    the stricter floor); otherwise remap the colour frame and convert the panorama.
    """
    m1, m2 = unwarper._m1, unwarper._m2
    t0, w0 = time.thread_time(), time.perf_counter()
    for f in frames:
        if grey_first:
            grey = cv2.remap(cv2.cvtColor(f, cv2.COLOR_BGR2GRAY), m1, m2, cv2.INTER_LINEAR)
        else:
            grey = cv2.cvtColor(cv2.remap(f, m1, m2, cv2.INTER_LINEAR), cv2.COLOR_BGR2GRAY)
        diff = cv2.absdiff(grey, bg)
        mask = cv2.threshold(diff, 22, 255, cv2.THRESH_BINARY)[1]
        cv2.connectedComponentsWithStats(mask, connectivity=8)
    return (time.thread_time() - t0) / len(frames), (time.perf_counter() - w0) / len(frames)


def _pipeline_pass(pipe: ImagePipeline, frames: list[Any], stats: dict[str, list[int]]) -> tuple[float, float]:
    t0, w0 = time.thread_time(), time.perf_counter()
    for k, f in enumerate(frames):
        out = pipe.process(f, round(k * 1e9 / STAMP_FPS), k)
        data = encode(out.features)
        stats["blobs"].append(len(out.features.blobs))
        stats["sightings"].append(len(out.features.sightings))
        stats["bytes"].append(len(data))
    return (time.thread_time() - t0) / len(frames), (time.perf_counter() - w0) / len(frames)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--site", default=str(REPO / "deploy" / "sites" / "demo.toml"))
    p.add_argument("--camera", default="pano1")
    p.add_argument("--frames", type=int, default=150)
    p.add_argument("--passes", type=int, default=5)
    p.add_argument("--t0", type=float, default=8.0, help="world time of the first frame (s)")
    args = p.parse_args(argv)
    cv2.setNumThreads(1)
    frames, annular, cyl, bodies = _frames(Path(args.site), args.camera, args.frames, args.t0)
    unwarper = Unwarper(annular)
    pipe = ImagePipeline(args.camera, PanoramicGeometry(cyl), PipelineSettings(), unwarper, bodies)
    for k, f in enumerate(frames):  # warm pass: the background model learns the scene
        pipe.process(f, round(k * 1e9 / STAMP_FPS), k)
    bg = cv2.cvtColor(cv2.remap(frames[0], unwarper._m1, unwarper._m2, cv2.INTER_LINEAR), cv2.COLOR_BGR2GRAY)
    stats: dict[str, list[int]] = {"blobs": [], "sightings": [], "bytes": []}
    # Interleaved passes, best of each: the machine may be shared, and the least-disturbed pass is the
    # closest to what the code costs.
    t_pipe, t_floor, t_floor_colour = [], [], []
    for _ in range(args.passes):
        t_pipe.append(_pipeline_pass(pipe, frames, stats))
        t_floor.append(_floor_pass(frames, unwarper, bg, grey_first=True))
        t_floor_colour.append(_floor_pass(frames, unwarper, bg, grey_first=False))
    per_pipe, per_floor, per_colour = (min(t[0] for t in ts) for ts in (t_pipe, t_floor, t_floor_colour))
    wall_pipe, wall_floor = min(t[1] for t in t_pipe), min(t[1] for t in t_floor)
    fps_pipe, fps_floor = 1.0 / per_pipe, 1.0 / per_floor
    result = {
        "benchmark": "sensor_node.pipeline",
        "frames_per_pass": len(frames),
        "passes": args.passes,
        "input": f"annular {frames[0].shape[1]}x{frames[0].shape[0]} BGR",
        "panorama": f"{annular.pano_w}x{annular.pano_h}",
        "threads": 1,
        "pipeline_fps": round(fps_pipe, 1),
        "pipeline_ms": round(per_pipe * 1e3, 3),
        "pipeline_ms_median_pass": round(statistics.median(t[0] for t in t_pipe) * 1e3, 3),
        "floor_fps": round(fps_floor, 1),
        "floor_ms": round(per_floor * 1e3, 3),
        "floor_ops": "cvtColor(annular->grey) + remap + absdiff + threshold + connectedComponentsWithStats",
        "floor_colour_remap_fps": round(1.0 / per_colour, 1),
        "floor_colour_remap_ops": "remap(BGR) + cvtColor(grey) + absdiff + threshold + connectedComponentsWithStats",
        "ratio_of_floor": round(fps_pipe / fps_floor, 3),
        "goal": {"fps": 300, "ratio_of_floor": 0.5},
        "meets_goal": bool(fps_pipe >= 300 and fps_pipe / fps_floor >= 0.5),
        "median_blobs": statistics.median(stats["blobs"]),
        "median_sightings": statistics.median(stats["sightings"]),
        "median_features_bytes": statistics.median(stats["bytes"]),
        "clock": "thread CPU time (time.thread_time): what one core spends, whoever else shares the machine",
        "wall_pipeline_fps": round(1.0 / wall_pipe, 1),
        "wall_floor_fps": round(1.0 / wall_floor, 1),
        "wall_ratio_of_floor": round(wall_floor / wall_pipe, 3),
        "load_average_1min": round(os.getloadavg()[0], 2),
    }
    json.dump(result, sys.stdout, indent=2)
    sys.stdout.write("\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
