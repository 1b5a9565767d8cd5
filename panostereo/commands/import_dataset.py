"""``panostereo import {mot,wildtrack} PATH --out DIR``: turn a dataset into a runnable site.

* ``mot``: any calibrated multi-view detection dataset laid out as ``calib/<cam>.json``,
  ``detections/<cam>.txt`` (MOTChallenge) and an optional ``gt.csv``
  (:mod:`panostereo.datasets.mot`); ``--fps`` is required, ``--area`` optional.
* ``wildtrack``: a Wildtrack-format dataset (Wildtrack; MultiviewX with ``--grid``
  options): annotations and calibrations, turned into the ``mot`` layout
  (:mod:`panostereo.datasets.wildtrack`); its annotated ground grid is the site's area.

Both write per-process configs and ``site.toml``, which ``panostereo demo
--site DIR/site.toml`` runs and ``panostereo evaluate-site DIR/site.toml``
plays in dataset time. The dataset stays where it is: pass its path, never copy
it into the repository.
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import asdict
from pathlib import Path

from common.area import AreaSpec, rectangle
from common.cli import non_negative, positive, probability
from common.errors import ConfigError
from panostereo.datasets.mot import import_mot
from panostereo.datasets.wildtrack import GridSpec, import_wildtrack

__all__ = ["configure", "parse_area", "run"]

RECTANGLE_VALUES = 4
"""``--area`` is X0,Y0,X1,Y1."""


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("format", choices=["mot", "wildtrack"], help="dataset layout")
    parser.add_argument("path", help="dataset folder")
    parser.add_argument("--out", required=True, metavar="DIR", help="where to write the site")
    parser.add_argument(
        "--noise-px", type=non_negative, default=0.0, help="Gaussian noise on box edges (pixels, 1 sigma)"
    )
    parser.add_argument(
        "--drop-rate", type=probability, default=0.0, help="fraction of boxes dropped (missed detections)"
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of the noise and drops")
    parser.add_argument("--name", default="", help="the site's name (default: the dataset folder's)")
    mot = parser.add_argument_group("mot")
    mot.add_argument("--fps", type=positive, default=None, help="mot: the dataset's frame rate (frame k at (k-1)/fps)")
    mot.add_argument(
        "--area",
        default=None,
        metavar="X0,Y0,X1,Y1",
        help="mot: the floor people can be in (m, world frame), if known: the site's [area], where people are "
        "started and every track is scored (edit site.toml for a polygon or exits)",
    )
    mot.add_argument(
        "--min-confidence",
        type=float,
        default=0.0,
        help="mot: the nodes ignore boxes whose conf column is lower (the detector's operating point)",
    )
    mot.add_argument(
        "--shared-detector",
        default="",
        metavar="NAME",
        help="mot: the boxes are one multi-view detector's floor detections drawn into every view (e.g. MVDeTr's), "
        "not each camera's own: its name. The views then find or miss a person together, covered or not",
    )
    wt = parser.add_argument_group("wildtrack")
    wt.add_argument("--frames", type=int, default=0, help="wildtrack: keep only the first N annotated frames (0: all)")
    wt.add_argument(
        "--grid",
        type=float,
        nargs=4,
        default=None,
        metavar=("X0", "Y0", "STEP", "WIDTH"),
        help="wildtrack: positionID grid: origin (m), step (m), cells per row (Wildtrack: -3 -9 0.025 480)",
    )
    wt.add_argument("--grid-rows", type=int, default=1440, help="wildtrack: positionID grid cells per column")
    wt.add_argument(
        "--extrinsic-unit-m", type=positive, default=0.01, help="wildtrack: metres per tvec unit (cm: 0.01)"
    )
    wt.add_argument(
        "--image-size",
        type=int,
        nargs=2,
        default=[1920, 1080],
        metavar=("W", "H"),
        help="wildtrack: the cameras' image size in pixels (default 1920 1080)",
    )


def parse_area(text: str) -> AreaSpec:
    """``X0,Y0,X1,Y1`` as the area of that rectangle.

    Raises:
        ConfigError: not four numbers, or a rectangle with no inside.
    """
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError as err:
        raise ConfigError(f"--area must be X0,Y0,X1,Y1 (four numbers, metres), got {text!r}") from err
    if len(values) != RECTANGLE_VALUES:
        raise ConfigError(f"--area must be X0,Y0,X1,Y1 (four numbers, metres), got {text!r}")
    return rectangle(*values)


def run(args: argparse.Namespace) -> int:
    if args.format == "mot":
        if args.fps is None:
            raise ConfigError("import mot: --fps is required (the dataset's frame rate)")
        res = import_mot(
            args.path,
            args.out,
            fps=args.fps,
            area=parse_area(args.area) if args.area is not None else None,
            min_confidence=args.min_confidence,
            shared_detector=args.shared_detector,
            noise_px=args.noise_px,
            drop_rate=args.drop_rate,
            seed=args.seed,
            name=args.name,
        )
    else:
        grid = GridSpec(rows=args.grid_rows, extrinsic_unit_m=args.extrinsic_unit_m)
        if args.grid is not None:
            x0, y0, step, width = args.grid
            grid = GridSpec(
                x0_m=x0,
                y0_m=y0,
                step_m=step,
                width=int(width),
                rows=args.grid_rows,
                extrinsic_unit_m=args.extrinsic_unit_m,
            )
        res = import_wildtrack(
            args.path,
            args.out,
            noise_px=args.noise_px,
            drop_rate=args.drop_rate,
            seed=args.seed,
            grid=grid,
            image_size=(args.image_size[0], args.image_size[1]),
            max_frames=args.frames,
            site_name=args.name,
        )
    print(json.dumps({k: str(v) if k == "site" else v for k, v in asdict(res).items()}, indent=2))
    _check_speed(res.site)
    print(f"run it: panostereo demo --site {res.site}")
    print(f"play it in dataset time: panostereo evaluate-site {res.site}")
    return 0


def _check_speed(site_path: str | Path) -> None:
    """Warn when the imported ground truth implies implausible walking speeds at the site's frame rate."""
    from common.site import load_site
    from user_agent.groundtruth import read_gt_csv, speed_warning

    site = load_site(site_path)
    if site.dataset is None or not site.dataset.ground_truth:
        return
    gt_path = site.resolve(site.dataset.ground_truth)
    if gt_path.is_file():
        warning = speed_warning(read_gt_csv(gt_path), site.dataset.fps)
        if warning:
            print(f"WARNING: {warning}", file=sys.stderr)
