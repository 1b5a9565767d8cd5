"""``panostereo import wildtrack PATH --out DIR [--noise-px N] [--drop-rate P]``.

Converts a Wildtrack-format dataset (Wildtrack; MultiviewX with ``--grid``
options) into a runnable site: calibration JSON and MOT detection file per
camera, ``gt.csv``, per-process configs and ``site.toml``, which
``panostereo demo --site DIR/site.toml`` runs and scores. The dataset stays
where it is: pass its path, never copy it into the repository.
"""

from __future__ import annotations

import argparse
import json
from dataclasses import asdict

from panostereo.datasets.wildtrack import GridSpec, import_wildtrack

__all__ = ["configure", "run"]


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("format", choices=["wildtrack"], help="dataset format")
    parser.add_argument("path", help="dataset folder (annotations_positions/, calibrations/)")
    parser.add_argument("--out", required=True, metavar="DIR", help="where to write the site")
    parser.add_argument("--noise-px", type=float, default=0.0, help="Gaussian noise on box edges (pixels, 1 sigma)")
    parser.add_argument("--drop-rate", type=float, default=0.0, help="fraction of boxes dropped (missed detections)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the noise and drops")
    parser.add_argument("--frames", type=int, default=0, help="keep only the first N annotated frames (0: all)")
    parser.add_argument(
        "--grid",
        type=float,
        nargs=4,
        default=None,
        metavar=("X0", "Y0", "STEP", "WIDTH"),
        help="positionID grid: origin (m), step (m), cells per row (Wildtrack: -3 -9 0.025 480)",
    )
    parser.add_argument("--extrinsic-unit-m", type=float, default=0.01, help="metres per tvec unit (cm: 0.01)")
    parser.add_argument("--image-size", type=int, nargs=2, default=[1920, 1080], metavar=("W", "H"))


def run(args: argparse.Namespace) -> int:
    grid = GridSpec(extrinsic_unit_m=args.extrinsic_unit_m)
    if args.grid is not None:
        x0, y0, step, width = args.grid
        grid = GridSpec(x0_m=x0, y0_m=y0, step_m=step, width=int(width), extrinsic_unit_m=args.extrinsic_unit_m)
    res = import_wildtrack(
        args.path,
        args.out,
        noise_px=args.noise_px,
        drop_rate=args.drop_rate,
        seed=args.seed,
        grid=grid,
        image_size=(args.image_size[0], args.image_size[1]),
        max_frames=args.frames,
    )
    print(json.dumps({k: str(v) if k == "site" else v for k, v in asdict(res).items()}, indent=2))
    print(f"run it: panostereo demo --site {res.site}")
    return 0
