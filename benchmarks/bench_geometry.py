"""Geometry micro-benchmarks: what the pure stages cost per call.

Usage::

    python -m benchmarks.bench_geometry [--repeat N]

Prints one JSON object: microseconds per call (median of ``repeat`` timing runs) for
``localize_pair``, ``intersect_rays`` (4 rays), ``pair_position_error``,
``optimal_configuration`` (the planner), and milliseconds for building the PAL
maps and for one ``cv2.remap`` unwarp of a 768x576 annular frame to 1080x162.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
import time
from collections.abc import Callable

import cv2
import numpy as np

from common.cameras import design_pal
from common.error_model import optimal_configuration, pair_position_error
from common.geometry import intersect_rays, localize_pair


def _per_call_s(fn: Callable[[], object], calls: int, repeat: int) -> float:
    runs = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        for _ in range(calls):
            fn()
        runs.append((time.perf_counter() - t0) / calls)
    return statistics.median(runs)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="bench_geometry", description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args(argv)
    o1, o2, t = np.array([0.0, 0.0]), np.array([3.0, 0.0]), np.array([1.7, 2.4])
    b1, b2 = math.atan2(2.4, 1.7), math.atan2(2.4, -1.3)
    origins = np.array([[0.0, 0.0], [3.0, 0.0], [0.0, 5.0], [4.0, 6.0]])
    bearings = np.arctan2(t[1] - origins[:, 1], t[0] - origins[:, 0])
    pal, _ = design_pal()
    annular = np.random.default_rng(0).integers(0, 255, (576, 768, 3), dtype=np.uint8)
    map_x, map_y = pal.unwarp_maps()
    r = args.repeat
    out = {
        "localize_pair_us": 1e6 * _per_call_s(lambda: localize_pair(o1, b1, 0.1, o2, b2, 0.1, 0.0035, 0.007), 2000, r),
        "intersect_rays_4_us": 1e6 * _per_call_s(lambda: intersect_rays(origins, bearings, 0.0035), 500, r),
        "pair_position_error_us": 1e6 * _per_call_s(lambda: pair_position_error(o1, o2, t, 0.0035), 5000, r),
        "optimal_configuration_ms": 1e3 * _per_call_s(lambda: optimal_configuration(6.0, 0.18), 5, r),
        "pal_maps_ms": 1e3 * _per_call_s(lambda: (pal.unwarp_maps(), pal.warp_maps()), 3, r),
        "unwarp_remap_ms": 1e3 * _per_call_s(lambda: cv2.remap(annular, map_x, map_y, cv2.INTER_LINEAR), 50, r),
    }
    json.dump({k: round(v, 3) for k, v in out.items()}, sys.stdout)
    sys.stdout.write("\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
