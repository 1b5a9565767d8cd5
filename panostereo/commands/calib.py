"""``panostereo calib``: bring a calibration in (``convert``), or refine a site's from people walking (``refine``).

Usage::

    panostereo calib refine SITE --out DIR [--fix CAM ...] [--frames N] [--recording REC.mcap] [--json]
    panostereo calib convert --from tsai View_001.xml --out view001.json
    panostereo calib convert --from opencv-yaml cam.yml --out cam.json [--units mm] [--image-size W H]
    panostereo calib convert --from p-matrix P.txt --image-size 768 576 --out cam.json [--units mm]

The JSON (``{"model": "pinhole", "image_size", "K", "dist", "R", "t"}``, metres,
world -> camera) is what ``[camera] calibration`` and ``[source] calibration``
read; see :mod:`common.calib_formats` for each format's conventions (Tsai:
millimetres, R = Rz Ry Rx, its radial distortion mapping the other way).

``refine`` takes every camera's current calibration as a starting guess and estimates its pose from the people
the cameras see (:mod:`panostereo.calib`), from a dataset site's detection files or a recording of the live site,
then writes the same site with the refined calibrations under ``--out`` and prints what moved.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from common.calib_formats import from_opencv_file, from_p_matrix, from_tsai_xml
from common.errors import ConfigError
from panostereo.calib import DEFAULT_INSTANTS

__all__ = ["configure", "run"]

UNITS = {"m": 1.0, "mm": 0.001, "cm": 0.01}


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the command's flags."""
    sub = parser.add_subparsers(dest="action", required=True)
    conv = sub.add_parser("convert", help="convert a calibration to the project's pinhole JSON")
    conv.add_argument("input", help="the calibration file")
    conv.add_argument(
        "--from",
        dest="fmt",
        required=True,
        choices=["tsai", "opencv-yaml", "p-matrix"],
        help="the input's format: a Tsai XML (PETS 2009), an OpenCV FileStorage YAML/XML, or a 3x4 P matrix",
    )
    conv.add_argument("--out", required=True, help="output JSON")
    conv.add_argument(
        "--image-size",
        type=int,
        nargs=2,
        metavar=("W", "H"),
        default=None,
        help="image width and height in pixels, when the file does not say (p-matrix: always needed)",
    )
    conv.add_argument(
        "--extrinsic",
        default=None,
        metavar="FILE",
        help="opencv-yaml: the pose (rvec or R, tvec) in a second file, as Wildtrack keeps it "
        "(intrinsic_zero/intr_CAM.xml with --extrinsic extrinsic/extr_CAM.xml)",
    )
    conv.add_argument("--units", choices=sorted(UNITS), default=None, help="translation units (tsai: always mm)")
    ref = sub.add_parser(
        "refine",
        help="refine the site's camera poses from people walking; write the refined site",
        description="Estimate every camera's pose (intrinsics kept) from the people the cameras see, starting "
        "from the site's current calibrations, and write the same site with the refined ones under --out.",
    )
    ref.add_argument(
        "site", metavar="SITE", help="the site file (a dataset site, or the live site a --recording was made of)"
    )
    ref.add_argument(
        "--out", required=True, metavar="DIR", help="folder for the refined site (the site's files, new calibrations)"
    )
    ref.add_argument(
        "--fix",
        action="append",
        default=[],
        metavar="CAM",
        help="a camera whose pose is surveyed: kept as it is, it holds the world frame (repeat for more)",
    )
    ref.add_argument(
        "--frames",
        type=int,
        default=DEFAULT_INSTANTS,
        metavar="N",
        help=f"use at most N instants, evenly spread over the data (default {DEFAULT_INSTANTS}; 0: all)",
    )
    ref.add_argument(
        "--recording", default=None, metavar="REC.mcap", help="an MCAP recording of the live site (agent record)"
    )
    ref.add_argument("--json", action="store_true", help="print a JSON object instead of a table")


def run(args: argparse.Namespace) -> int:
    """The chosen action."""
    if args.action == "refine":
        return _refine(args)
    return _convert(args)


def _refine(args: argparse.Namespace) -> int:
    """Refine, write the site, print per camera what moved and the residuals."""
    from panostereo.calib.cli import refine_site

    report = refine_site(args.site, args.out, fix=args.fix, frames=args.frames, recording=args.recording)
    if args.json:
        print(json.dumps(report, indent=1))
    else:
        from panostereo.calib.cli import format_report

        print(format_report(report))
    return 0


def _convert(args: argparse.Namespace) -> int:
    """Convert and write; prints where the camera is."""
    src = Path(args.input)
    try:
        text = src.read_text()
    except (OSError, UnicodeDecodeError) as err:
        raise ConfigError(f"cannot read calibration {str(src)!r}: {err}") from err
    size = tuple(args.image_size) if args.image_size else None
    if size is not None and min(size) < 1:
        raise ConfigError(f"--image-size: expected two positive integers, got {list(size)}")
    if args.extrinsic and args.fmt != "opencv-yaml":
        raise ConfigError(f"--extrinsic goes with --from opencv-yaml (a pose in its own file), not {args.fmt}")
    if args.fmt == "tsai":
        if args.units not in (None, "mm"):
            raise ConfigError(f"--units: Tsai calibrations are in mm, got {args.units!r}")
        cal = from_tsai_xml(text, str(src))
    elif args.fmt == "opencv-yaml":
        extrinsic = Path(args.extrinsic) if args.extrinsic else None
        cal = from_opencv_file(src, units_m=UNITS[args.units or "m"], image_size=size, extrinsic=extrinsic)
    else:
        if size is None:
            raise ConfigError("--from p-matrix needs --image-size W H")
        cal = from_p_matrix(text, size, units_m=UNITS[args.units or "m"], source=str(src))
    out = Path(args.out)
    out.write_text(json.dumps(cal, indent=1) + "\n")
    from common.pinhole import PinholeCamera

    c = PinholeCamera.from_calibration(cal, str(out)).center_world
    print(f"{out}: {cal['image_size'][0]}x{cal['image_size'][1]} px, camera at ({c[0]:.3f}, {c[1]:.3f}, {c[2]:.3f}) m")
    return 0
