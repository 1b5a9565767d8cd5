"""``panostereo render``: one simulated camera frame, for looking at.

Usage::

    panostereo render --site deploy/sites/demo.toml --camera pano1 --time 5 --out frame.png

For a panoramic camera writes the raw annular frame (``frame.png``) and its
panorama unwarped with the camera's own lens model (``frame_pano.png``), i.e.
what the sensor node's unwarp stage produces; for a PTZ camera writes the
perspective frame for ``--pan/--tilt/--zoom`` (default: the site's). Prints a
JSON summary of where the people and other cameras are (ground truth, with the
panorama column each head should appear at) so the frame can be checked by eye.
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import sys
from pathlib import Path
from typing import Any

import cv2
import msgspec
import numpy as np

from common.errors import ConfigError
from common.site import load_site
from sim.render.cameras import PanoramicRenderer, PtzRenderer
from sim.world import World, sensor_bearing, site_with_seed, site_with_seed_from_env

__all__ = ["configure", "run"]

logger = logging.getLogger(__name__)


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the command's flags."""
    parser.add_argument("--site", required=True, help="site file (deploy/sites/*.toml)")
    parser.add_argument("--camera", required=True, help="camera id in the site")
    parser.add_argument("--time", type=float, default=0.0, help="world time in seconds (default 0)")
    parser.add_argument("--out", required=True, help="output PNG (a panoramic camera also writes <stem>_pano.png)")
    parser.add_argument("--seed", type=int, default=None, help="override the site's seed (else env PANOSTEREO_SEED)")
    parser.add_argument("--no-noise", action="store_true", help="render without sensor noise")
    parser.add_argument("--pan", type=float, default=None, help="PTZ pan in degrees (world azimuth)")
    parser.add_argument("--tilt", type=float, default=None, help="PTZ tilt in degrees (> 0 up)")
    parser.add_argument("--zoom", type=float, default=None, help="PTZ zoom factor")


def _write(path: Path, img: np.ndarray[Any, Any]) -> None:
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        ok = cv2.imwrite(str(path), img)
    except (OSError, cv2.error) as err:
        reason = " ".join(str(err).split())
        raise ConfigError(f"--out {path}: cannot write the image ({reason})") from err
    if not ok:
        raise ConfigError(f"--out {path}: cannot write the image (unsupported extension or unwritable file)")


def run(args: argparse.Namespace) -> int:
    """Render the frame(s) and print the summary."""
    site = site_with_seed(site_with_seed_from_env(load_site(args.site)), args.seed)
    if not math.isfinite(args.time) or args.time < 0:
        raise ConfigError(f"--time must be a finite number >= 0, got {args.time}")
    cam = site.camera_by_id(args.camera)
    world = World.from_site(site)
    lighting = site.world.lighting
    if args.no_noise:
        lighting = msgspec.structs.replace(lighting, noise_sigma=0.0)
    rng = np.random.default_rng([site.site.seed, round(args.time * 1000)])
    out = Path(args.out)
    summary: dict[str, Any] = {"site": site.site.name, "camera": cam.id, "time_s": args.time, "files": [str(out)]}
    if cam.kind == "panoramic":
        renderer = PanoramicRenderer(world, cam, lighting)
        raw = renderer.render(args.time, rng)
        annular, cyl = renderer.models
        map_x, map_y = annular.unwarp_maps()
        pano = cv2.remap(raw, map_x, map_y, cv2.INTER_LINEAR)
        _write(out, raw)
        pano_path = out.with_name(out.stem + "_pano" + (out.suffix or ".png"))
        _write(pano_path, pano)
        summary["files"].append(str(pano_path))
        me = world.platform_at(cam.id, args.time)
        summary["people"] = [
            {
                "id": p.person_id,
                "x_m": round(p.x_m, 3),
                "y_m": round(p.y_m, 3),
                "height_m": round(p.height_m, 3),
                "head_col": round(float(cyl.col_from_bearing(sensor_bearing(me, p.x_m, p.y_m))), 1),
            }
            for p in world.people_at(args.time)
            if p.present
        ]
        summary["platforms"] = [
            {
                "id": pl.sensor_id,
                "col": round(float(cyl.col_from_bearing(sensor_bearing(me, pl.x_m, pl.y_m))), 1),
                "distance_m": round(math.hypot(pl.x_m - me.x_m, pl.y_m - me.y_m), 3),
            }
            for pl in world.platforms_at(args.time)
            if pl.sensor_id != cam.id
        ]
    else:
        ptz = PtzRenderer(world, cam, lighting)
        pan = math.radians(cam.pan_deg if args.pan is None else args.pan)
        tilt = math.radians(cam.tilt_deg if args.tilt is None else args.tilt)
        zoom = cam.zoom if args.zoom is None else float(args.zoom)
        _write(out, ptz.render(args.time, pan, tilt, zoom, rng))
        summary["ptz"] = {"pan_deg": math.degrees(pan), "tilt_deg": math.degrees(tilt), "zoom": zoom}
    sys.stdout.write(json.dumps(summary, indent=1) + "\n")
    return 0
