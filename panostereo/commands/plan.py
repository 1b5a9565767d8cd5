"""``panostereo plan``: the best stereo configuration for a target and the error map (Eqs. 4-6, Fig. 4).

Camera 1 (the main camera) is at O1, the target T at distance D1; camera 2 can
move. Under model M1 (docs/geometry.md section 2) the command prints the
optimal baseline and angle, camera 2's two symmetric optimal positions (frame:
O1 = (0, 0), T = (D1, 0)), the normalised error dD1/(D1 dphi), the absolute error
for the given bearing error, Eq. (5)'s bound and Eq. (6)'s fixed-baseline error.
``--map`` draws Fig. 4 as a PNG.
"""

from __future__ import annotations

import argparse
import json
import logging
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt

from common.error_model import (
    OptimalConfig,
    eq5_bound,
    eq6_fixed_baseline,
    error_map,
    optimal_configuration,
)
from common.errors import ConfigError

logger = logging.getLogger(__name__)

__all__ = ["configure", "plan_result", "render_error_map", "run"]


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--distance", type=float, required=True, help="D1: distance camera 1 -> target (m)")
    parser.add_argument("--radius", type=float, required=True, help="R: radius of the robots' cylindrical body (m)")
    parser.add_argument(
        "--bearing-error-deg", type=float, default=0.2, help="angular error of every bearing (deg; paper: 0.2)"
    )
    parser.add_argument("--map", type=Path, default=None, help="write the Fig. 4 error map to this PNG")
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of text")


def plan_result(distance_m: float, radius_m: float, bearing_error_deg: float) -> tuple[dict[str, Any], OptimalConfig]:
    """The numbers ``plan`` prints, and the optimum they come from."""
    if not (math.isfinite(radius_m) and radius_m > 0):
        raise ConfigError(f"--radius must be > 0, got {radius_m}")
    if not (math.isfinite(distance_m) and distance_m > 2 * radius_m):
        raise ConfigError(f"--distance must be > 2 * radius = {2 * radius_m:g} m, got {distance_m}")
    if not (math.isfinite(bearing_error_deg) and bearing_error_deg > 0):
        raise ConfigError(f"--bearing-error-deg must be > 0, got {bearing_error_deg}")
    dphi = math.radians(bearing_error_deg)
    cfg = optimal_configuration(distance_m, radius_m)
    result = {
        "baseline_m": cfg.baseline_m,
        "phi1_deg": math.degrees(cfg.phi1_rad),
        "o2_positions_m": [list(cfg.o2_xy_pair[0]), list(cfg.o2_xy_pair[1])],
        "normalised_error": cfg.normalised_error,
        "error_m": cfg.normalised_error * distance_m * dphi,
        "eq5_bound_m": eq5_bound(distance_m, radius_m, dphi),
        "eq6_fixed_baseline_m": eq6_fixed_baseline(distance_m, radius_m, dphi),
    }
    return result, cfg


def _check_map_path(path: Path) -> None:
    """Fail before any work if ``--map`` cannot become a PNG file."""
    if path.suffix.lower() != ".png":
        raise ConfigError(f"--map {path}: expected a file name ending in .png, got {path.suffix or 'no suffix'!r}")
    if path.is_dir():
        raise ConfigError(f"--map {path}: is a directory, expected a .png file path")
    if not path.parent.is_dir():
        raise ConfigError(f"--map {path}: cannot write a PNG there (directory {path.parent} does not exist)")


def _write_png(path: Path, image: np.ndarray) -> None:
    try:
        ok = cv2.imwrite(str(path), image)
    except cv2.error as err:
        raise ConfigError(
            f"--map {path}: cannot write a PNG there ({err.msg if hasattr(err, 'msg') else err})"
        ) from err
    if not ok:
        raise ConfigError(f"--map {path}: cannot write a PNG there (permission denied or disk full?)")
    logger.info("wrote error map %s", path)


def run(args: argparse.Namespace) -> int:
    if args.map is not None:
        _check_map_path(args.map)
    result, cfg = plan_result(args.distance, args.radius, args.bearing_error_deg)
    if args.map is not None:
        _write_png(args.map, render_error_map(args.distance, args.radius, cfg))
    if args.json:
        print(json.dumps(result))
        return 0
    (xa, ya), (xb, yb) = result["o2_positions_m"]
    lines = [
        f"target distance D1 = {args.distance:g} m, robot radius R = {args.radius:g} m, "
        f"bearing error {args.bearing_error_deg:g} deg (model M1)",
        f"best baseline       baseline_m           = {result['baseline_m']:.4f} m"
        f"   (Eq. 4: 2*sqrt(D1*R) = {2 * math.sqrt(args.distance * args.radius):.4f} m)",
        f"best angle at O1    phi1_deg             = {result['phi1_deg']:.3f} deg",
        f"camera 2 optima     o2_positions_m       = ({xa:.4f}, {ya:+.4f}) and ({xb:.4f}, {yb:+.4f}) m"
        f"   (O1 = (0, 0), T = ({args.distance:g}, 0))",
        f"normalised error    normalised_error     = {result['normalised_error']:.4f}   (dD1 / (D1 dphi))",
        f"distance error      error_m              = {result['error_m']:.4f} m",
        f"Eq. 5 bound         eq5_bound_m          = {result['eq5_bound_m']:.4f} m",
        f"Eq. 6 fixed B = 2R  eq6_fixed_baseline_m = {result['eq6_fixed_baseline_m']:.4f} m",
    ]
    print("\n".join(lines))
    return 0


# --------------------------------------------------------------------------------------------------
# Fig. 4 as a PNG (OpenCV drawing only)
# --------------------------------------------------------------------------------------------------

_FONT = cv2.FONT_HERSHEY_SIMPLEX
_BLACK = (0, 0, 0)
_WHITE = (255, 255, 255)


def _text(img: npt.NDArray[np.uint8], s: str, org: tuple[int, int], scale: float = 0.45, **kw: Any) -> None:
    color = kw.get("color", _BLACK)
    anchor = kw.get("anchor", "left")
    (w, h), _ = cv2.getTextSize(s, _FONT, scale, 1)
    x, y = org
    if anchor == "center":
        x -= w // 2
    elif anchor == "right":
        x -= w
    if kw.get("vcenter"):
        y += h // 2
    if kw.get("boxed"):
        cv2.rectangle(img, (x - 3, y - h - 4), (x + w + 3, y + 5), _WHITE, -1)
        cv2.rectangle(img, (x - 3, y - h - 4), (x + w + 3, y + 5), _BLACK, 1)
    cv2.putText(img, s, (x, y), _FONT, scale, color, 1, cv2.LINE_AA)


def _nice_step(span: float, target_ticks: int = 8) -> float:
    raw = span / target_ticks
    mag = 10 ** math.floor(math.log10(raw))
    return float(min((m * mag for m in (1, 2, 5, 10)), key=lambda s: abs(s - raw)))


def render_error_map(d1_m: float, radius_m: float, cfg: OptimalConfig, px_per_m: float | None = None) -> np.ndarray:
    """Fig. 4: normalised error dD1/(D1 dphi) over camera 2's position, log colour scale, optima marked.

    Blue is small error, red large (as in the paper); the colour bar spans the
    optimum E* to 4 E* (clipped above). The dashed curve is the locus of per-B
    optima (cos phi1 = 3 B D1 / (2 D1^2 + B^2), B < D1): the caption's "elliptic curve".
    """
    x0, x1 = -0.25 * d1_m, 1.25 * d1_m
    y0, y1 = -0.6 * d1_m, 0.6 * d1_m
    scale = px_per_m if px_per_m is not None else 640.0 / (x1 - x0)
    w_px, h_px = round((x1 - x0) * scale), round((y1 - y0) * scale)
    step = (x1 - x0) / w_px
    emap = error_map(d1_m, radius_m, (x0 + step / 2, x1 - step / 2, y0 + step / 2, y1 - step / 2), step)
    e_star = cfg.normalised_error
    e_max = 4.0 * e_star
    err = np.where(np.isfinite(emap.error), emap.error, e_max)
    level = np.clip(np.log(err / e_star) / math.log(e_max / e_star), 0.0, 1.0)
    gray = np.flipud((level * 255).astype(np.uint8))  # row 0 = top = largest y
    field = cv2.applyColorMap(gray, cv2.COLORMAP_JET)[:h_px, :w_px]

    left, top, bar_w, right, bottom = 70, 50, 22, 110, 60
    img = np.full((top + field.shape[0] + bottom, left + field.shape[1] + 30 + bar_w + right - 30, 3), 255, np.uint8)
    img[top : top + field.shape[0], left : left + field.shape[1]] = field

    def to_px(x: float, y: float) -> tuple[int, int]:
        return round(left + (x - x0) * scale), round(top + (y1 - y) * scale)

    # Per-B optimum locus ("elliptic curve" of the caption), both halves.
    bs = np.linspace(2 * radius_m, 0.999 * d1_m, 200)
    cos_phi = 3 * bs * d1_m / (2 * d1_m**2 + bs**2)
    for sgn in (1, -1):
        pts = np.array([to_px(b * c, sgn * b * math.sqrt(1 - c * c)) for b, c in zip(bs, cos_phi, strict=True)])
        for i in range(0, len(pts) - 1, 2):
            cv2.line(img, tuple(map(int, pts[i])), tuple(map(int, pts[i + 1])), _WHITE, 1, cv2.LINE_AA)

    # Axes: frame, ticks and labels in metres.
    cv2.rectangle(img, (left - 1, top - 1), (left + field.shape[1], top + field.shape[0]), _BLACK, 1)
    tick = _nice_step(x1 - x0)
    for xv in np.arange(math.ceil(x0 / tick) * tick, x1 + 1e-9, tick):
        px, _ = to_px(float(xv), 0.0)
        cv2.line(img, (px, top + field.shape[0]), (px, top + field.shape[0] + 5), _BLACK, 1)
        _text(img, f"{xv:g}", (px, top + field.shape[0] + 20), anchor="center")
    for yv in np.arange(math.ceil(y0 / tick) * tick, y1 + 1e-9, tick):
        _, py = to_px(0.0, float(yv))
        cv2.line(img, (left - 5, py), (left - 1, py), _BLACK, 1)
        _text(img, f"{yv:g}", (left - 8, py), anchor="right", vcenter=True)
    _text(img, "x (m), along O1 -> T", (left + field.shape[1] // 2, top + field.shape[0] + 45), 0.5, anchor="center")
    _y_label(img, top + field.shape[0] // 2)
    _text(
        img,
        f"Fig. 4 error map dD1/(D1 dphi), model M1: D1 = {d1_m:g} m, R = {radius_m:g} m",
        (left, 22),
        0.55,
    )
    _text(
        img,
        f"optimum B = {cfg.baseline_m:.3f} m, phi1 = {math.degrees(cfg.phi1_rad):.2f} deg, "
        f"E* = {e_star:.3f}; dashed: best O2 for each baseline",
        (left, 42),
        0.45,
    )

    _mark_optima(img, to_px, d1_m, cfg)
    _colour_bar(img, (left + field.shape[1] + 30, top), field.shape[0], bar_w, (e_star, e_max))
    return img


def _mark_optima(
    img: np.ndarray, to_px: Callable[[float, float], tuple[int, int]], d1_m: float, cfg: OptimalConfig
) -> None:
    """Markers on the error map: camera 1 (O1), the target (T), and both optimal places of camera 2 with their rays."""
    o1, t = to_px(0.0, 0.0), to_px(d1_m, 0.0)
    cv2.circle(img, o1, 7, _WHITE, -1, cv2.LINE_AA)
    cv2.circle(img, o1, 7, _BLACK, 2, cv2.LINE_AA)
    _text(img, "O1", (o1[0] - 30, o1[1] + 28), 0.5, boxed=True)
    cv2.drawMarker(img, t, _WHITE, cv2.MARKER_TILTED_CROSS, 18, 4, cv2.LINE_AA)
    cv2.drawMarker(img, t, _BLACK, cv2.MARKER_TILTED_CROSS, 18, 2, cv2.LINE_AA)
    _text(img, "T", (t[0] - 5, t[1] + 30), 0.5, boxed=True)
    for k, (ox, oy) in enumerate(cfg.o2_xy_pair):
        p = to_px(ox, oy)
        cv2.line(img, o1, p, _WHITE, 1, cv2.LINE_AA)
        cv2.line(img, p, t, _WHITE, 1, cv2.LINE_AA)
        cv2.drawMarker(img, p, _BLACK, cv2.MARKER_STAR, 20, 4, cv2.LINE_AA)
        cv2.drawMarker(img, p, _WHITE, cv2.MARKER_STAR, 18, 2, cv2.LINE_AA)
        label = f"O2* ({ox:.2f}, {oy:+.2f}) m"
        _text(img, label, (p[0] + 14, p[1] + (-12 if k == 0 else 24)), 0.45, boxed=True)


def _y_label(img: np.ndarray, centre_row: int) -> None:
    """The y axis's label, written upwards at the image's left edge, centred on ``centre_row``."""
    ylab = np.full((22, 120, 3), 255, np.uint8)
    _text(ylab, "y (m)", (60, 16), 0.5, anchor="center")
    ylab_rot = np.asarray(cv2.rotate(ylab, cv2.ROTATE_90_COUNTERCLOCKWISE), dtype=np.uint8)
    yc = centre_row - ylab_rot.shape[0] // 2
    img[yc : yc + ylab_rot.shape[0], 4 : 4 + ylab_rot.shape[1]] = ylab_rot


MIN_TICKS = 4
"""The colour bar has at least this many labelled ticks (round values where they fit, else log-spaced)."""


def _colour_bar(img: np.ndarray, corner: tuple[int, int], bar_h: int, bar_w: int, span: tuple[float, float]) -> None:
    """The error map's colour bar (log scale E* .. E_max) with tick labels, its top-left corner at ``corner``."""
    bx, top = corner
    e_star, e_max = span
    ramp = np.linspace(255, 0, bar_h).astype(np.uint8)[:, None].repeat(bar_w, axis=1)
    img[top : top + bar_h, bx : bx + bar_w] = cv2.applyColorMap(ramp, cv2.COLORMAP_JET)
    cv2.rectangle(img, (bx - 1, top - 1), (bx + bar_w, top + bar_h), _BLACK, 1)
    ticks = [e_star, *(v for v in (15, 20, 25, 30, 35, 40, 50) if e_star * 1.08 < v < e_max * 0.95), e_max]
    if len(ticks) < MIN_TICKS:
        ticks = [float(e_star * (e_max / e_star) ** f) for f in (0, 0.25, 0.5, 0.75, 1.0)]
    for v in ticks:
        f = math.log(v / e_star) / math.log(e_max / e_star)
        py = round(top + (1 - f) * (bar_h - 1))
        cv2.line(img, (bx + bar_w, py), (bx + bar_w + 5, py), _BLACK, 1)
        _text(img, f"{v:.1f}" if v in (e_star, e_max) else f"{v:g}", (bx + bar_w + 8, py), anchor="left", vcenter=True)
    _text(img, "dD1/(D1 dphi)", (bx - 10, top + bar_h + 22), 0.42)
    _text(img, f">= {e_max:.1f} clipped", (bx - 10, top + bar_h + 40), 0.38)
