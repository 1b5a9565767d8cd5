"""Distance-error model of adaptive panoramic stereo: the paper's Eqs. (4)-(6) and Fig. 4.

Model M1 (docs/geometry.md section 2): every measured angle carries the same
error dphi -- the bearings phi1, phi2 and the angle alpha subtended by the other
robot's cylinder (Eq. 3) -- and the first-order terms add in the worst case::

    dD1 = [ D1 B / (2R) + D1 |cot phi0| + D2 / sin phi0 ] dphi

The first term is the mutual-calibration baseline error (dD1/dB = D1/B times
|dB/dalpha| ~ B^2/(2R)); it vanishes when the poses are surveyed. With O1 =
(0, 0), T = (D1, 0) and O2 = (x, y) the normalised error of Fig. 4 is::

    dD1 / (D1 dphi) = sqrt(x^2 + y^2) / (2R) + [D1 |D1 - x| + (D1 - x)^2 + y^2] / (D1 |y|)

Its minimum (two symmetric points) is the optimal configuration; Eq. (4)'s
cos phi1 = 3 B D1 / (2 D1^2 + B^2) holds exactly at it, B ~ 2 sqrt(D1 R) is its
asymptote, Eq. (5) bounds it and Eq. (6) is the fixed-baseline (B = 2R) best case.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
from scipy import optimize

from common.arrays import FloatArray
from common.errors import GeometryError

__all__ = [
    "MAX_ERROR_M",
    "ErrorMap",
    "OptimalConfig",
    "eq5_bound",
    "eq6_fixed_baseline",
    "error_map",
    "m1_error",
    "normalised_error_xy",
    "optimal_configuration",
    "optimal_positions_world",
    "pair_error_f",
    "pair_position_error",
    "pair_position_errors",
]


MAX_ERROR_M = 1.0e4
"""Cap of :func:`pair_position_error` for degenerate geometry (fits the wire's bounded floats)."""


def _baseline_term(b: Any, radius_m: float, exact: bool) -> Any:
    """|dB/dalpha| / B ... times D1 gives dD1^B: B/(2R) (approximate) or sqrt(B^2 - R^2)/(2R) (exact)."""
    b = np.asarray(b, dtype=np.float64)
    if exact:
        return np.sqrt(np.maximum(b * b - radius_m * radius_m, 0.0)) / (2.0 * radius_m)
    return b / (2.0 * radius_m)


def m1_error(  # noqa: PLR0917 - positional signature fixed by the team contract
    o1_xy: npt.ArrayLike,
    o2_xy: npt.ArrayLike,
    target_xy: npt.ArrayLike,
    radius_m: float,
    bearing_err_rad: float,
    baseline_known: bool,
    exact_baseline: bool = False,
) -> Any:
    """Model M1: worst-case first-order error dD1 (m) of the distance O1-T measured with the pair (O1, O2).

    ``baseline_known`` (surveyed poses) drops the mutual-calibration term D1 B / (2R).
    ``target_xy`` may be (2,) (returns a float) or (N, 2) (returns an array); inf where
    the target is colinear with the cameras (sin phi0 = 0).
    """
    if not radius_m > 0 and not baseline_known:
        raise GeometryError(f"the robot radius R must be > 0 for mutual calibration, got {radius_m}")
    o1 = np.asarray(o1_xy, dtype=np.float64)
    o2 = np.asarray(o2_xy, dtype=np.float64)
    t = np.asarray(target_xy, dtype=np.float64)
    v1, v2 = t - o1, t - o2
    d1 = np.hypot(v1[..., 0], v1[..., 1])
    d2 = np.hypot(v2[..., 0], v2[..., 1])
    b = float(np.hypot(*(o2 - o1)))
    with np.errstate(divide="ignore", invalid="ignore"):
        sin0 = np.abs(v1[..., 0] * v2[..., 1] - v1[..., 1] * v2[..., 0]) / (d1 * d2)
        cos0 = (v1[..., 0] * v2[..., 0] + v1[..., 1] * v2[..., 1]) / (d1 * d2)
        # dD1/dphi1 = D1 cot phi0 and dD1/dphi2 = D2 / sin phi0 (notes table, from Eq. 1).
        angles = np.where(sin0 > 0, d1 * np.abs(cos0) / sin0 + d2 / sin0, np.inf)
    base = 0.0 if baseline_known else d1 * _baseline_term(b, radius_m, exact_baseline)
    out = (base + angles) * bearing_err_rad
    return float(out) if np.ndim(out) == 0 else out


def normalised_error_xy(x: Any, y: Any, d1_m: float, radius_m: float, exact_baseline: bool = False) -> Any:
    """Fig. 4: dD1 / (D1 dphi) for O2 at (x, y), with O1 = (0, 0) and T = (d1, 0). Vectorised; inf on y = 0."""
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    ay = np.abs(y)
    with np.errstate(divide="ignore", invalid="ignore"):
        tri = np.where(ay > 0, (d1_m * np.abs(d1_m - x) + (d1_m - x) ** 2 + y * y) / (d1_m * ay), np.inf)
    out = _baseline_term(np.hypot(x, y), radius_m, exact_baseline) + tri
    return float(out) if np.ndim(out) == 0 else out


@dataclass(frozen=True, slots=True)
class OptimalConfig:
    """The best place for camera 2 given camera 1 and the target (Conclusion 1, Fig. 4)."""

    baseline_m: float
    phi1_rad: float
    """Angle at O1 between the target and O2."""
    o2_xy_pair: tuple[tuple[float, float], tuple[float, float]]
    """The two symmetric optima in the frame O1 = (0, 0), T = (D1, 0): (x, +y) and (x, -y)."""
    normalised_error: float
    """dD1 / (D1 dphi) at the optimum."""


def optimal_configuration(
    d1_m: float, radius_m: float, exact_baseline: bool = False, min_d2_m: float | None = None
) -> OptimalConfig:
    """Minimise Fig. 4's map: the optimal baseline and angle under model M1.

    Camera 2 must stay clear of camera 1 (B > 2R) and of the target (D2 >= ``min_d2_m``,
    default D1 / 2): M1 only counts the error of D1, so it also rewards parking
    camera 2 on the target itself (D2 -> 0, where D1 is just the baseline), which is
    no stereo configuration; the minimum the paper discusses (Conclusion 1, Fig. 4)
    is the interior one. A coarse polar grid over (B, phi1) finds the basin, then
    Nelder-Mead polishes it to ~1e-9.

    Raises:
        GeometryError: D1 or R not positive, or D1 <= 2R (the target touches the robots).
    """
    if not (d1_m > 0 and radius_m > 0) or d1_m <= 2 * radius_m:
        raise GeometryError(f"need D1 > 2R > 0, got D1={d1_m} m, R={radius_m} m")
    min_d2 = d1_m / 2 if min_d2_m is None else min_d2_m

    def cost(p: FloatArray) -> float:
        b, phi = float(p[0]), float(p[1])
        x, y = b * math.cos(phi), b * math.sin(phi)
        if b <= 2 * radius_m or not 0 < phi < math.pi or math.hypot(d1_m - x, y) < min_d2:
            return math.inf
        return float(normalised_error_xy(x, y, d1_m, radius_m, exact_baseline))

    bs = np.linspace(2 * radius_m * 1.01, 3 * d1_m, 300)
    phis = np.linspace(0.005, math.pi - 0.005, 300)
    bb, pp = np.meshgrid(bs, phis)
    xx, yy = bb * np.cos(pp), bb * np.sin(pp)
    grid = normalised_error_xy(xx, yy, d1_m, radius_m, exact_baseline)
    grid = np.where(np.hypot(d1_m - xx, yy) < min_d2, np.inf, grid)
    i = np.unravel_index(int(np.argmin(grid)), grid.shape)
    res = optimize.minimize(
        cost,
        np.array([bb[i], pp[i]]),
        method="Nelder-Mead",
        options={"xatol": 1e-10, "fatol": 1e-12, "maxiter": 4000},
    )
    b, phi = float(res.x[0]), float(res.x[1])
    x, y = b * math.cos(phi), b * math.sin(phi)
    return OptimalConfig(baseline_m=b, phi1_rad=phi, o2_xy_pair=((x, y), (x, -y)), normalised_error=float(res.fun))


def optimal_positions_world(
    o1_xy: npt.ArrayLike, target_xy: npt.ArrayLike, radius_m: float
) -> tuple[FloatArray, FloatArray, OptimalConfig]:
    """The two optimal world positions of camera 2 for camera 1 at ``o1_xy`` looking at ``target_xy``."""
    o1 = np.asarray(o1_xy, dtype=np.float64)
    v = np.asarray(target_xy, dtype=np.float64) - o1
    d1 = float(np.hypot(*v))
    cfg = optimal_configuration(d1, radius_m)  # raises GeometryError unless D1 > 2R
    c, s = v / d1
    rot = np.array([[c, -s], [s, c]])
    p_a = o1 + rot @ np.asarray(cfg.o2_xy_pair[0])
    p_b = o1 + rot @ np.asarray(cfg.o2_xy_pair[1])
    return p_a, p_b, cfg


def eq5_bound(d1: float, radius: float, dphi: float) -> float:
    """Eq. (5): the optimal configuration's error is below 2 D1 sqrt(D1 / R) dphi (m)."""
    return 2.0 * d1 * math.sqrt(d1 / radius) * dphi


def eq6_fixed_baseline(d1: float, radius: float, dphi: float) -> float:
    """Eq. (6): best-case error (m) of a fixed stereo head with accurate baseline B = 2R.

    Returns the exact minimum over phi1 under M1 without the calibration term,
    sqrt((4 D1^2 - B^2)(D1^2 - B^2)) / B * dphi, whose leading term is Eq. (6)'s
    D1^2 / R * dphi (docs/geometry.md section 2.2).
    """
    b = 2.0 * radius
    if not d1 > b:
        raise GeometryError(f"Eq. (6) needs D1 > B = 2R, got D1={d1} m, R={radius} m")
    return math.sqrt((4 * d1 * d1 - b * b) * (d1 * d1 - b * b)) / b * dphi


@dataclass(frozen=True, slots=True, eq=False)
class ErrorMap:
    """Fig. 4 sampled on a grid: ``error[j, i]`` is dD1/(D1 dphi) with O2 at (x_m[i], y_m[j])."""

    x_m: FloatArray
    y_m: FloatArray
    error: FloatArray
    """(ny, nx); inf on the O1-T line (y = 0)."""
    d1_m: float
    radius_m: float


def error_map(d1: float, radius: float, extent_m: float | tuple[float, float, float, float], step_m: float) -> ErrorMap:
    """Fig. 4's error map over O2 positions (O1 at the origin, T at (d1, 0)).

    Args:
        d1: distance O1-T (m).
        radius: robot radius R (m).
        extent_m: (x_min, x_max, y_min, y_max), or a half-size e for the square
            [d1/2 - e, d1/2 + e] x [-e, e] centred on the O1-T midpoint.
        step_m: grid step (m).
    """
    if isinstance(extent_m, tuple):
        x0, x1, y0, y1 = extent_m
    else:
        x0, x1, y0, y1 = d1 / 2 - extent_m, d1 / 2 + extent_m, -extent_m, extent_m
    if not (step_m > 0 and x1 > x0 and y1 > y0):
        raise GeometryError(f"error map needs step > 0 and a non-empty extent, got {extent_m}, step {step_m}")
    xs = x0 + step_m * np.arange(math.floor((x1 - x0) / step_m + 1e-9) + 1, dtype=np.float64)
    ys = y0 + step_m * np.arange(math.floor((y1 - y0) / step_m + 1e-9) + 1, dtype=np.float64)
    xs, ys = np.asarray(xs, dtype=np.float64), np.asarray(ys, dtype=np.float64)
    xx, yy = np.meshgrid(xs, ys)
    return ErrorMap(x_m=xs, y_m=ys, error=normalised_error_xy(xx, yy, d1, radius), d1_m=d1, radius_m=radius)


def pair_position_error(
    o1_xy: npt.ArrayLike,
    o2_xy: npt.ArrayLike,
    target_xy: npt.ArrayLike,
    sigma_bearing_rad: float,
    sigma_baseline_m: float = 0.0,
) -> float:
    """Predicted RMS position error (m) of localising the target with this pair (Gaussian errors).

    Bearing noise sigma on both rays gives sigma sqrt(D1^2 + D2^2) / sin phi0
    (first order, Eq. 1); a baseline error sigma_B scales the triangle about O1
    and adds D1 sigma_B / B in quadrature. Degenerate geometry (target on the
    baseline line or at a camera) gives a large value, capped at MAX_ERROR_M.
    :func:`pair_position_errors` is the same for many pairs at once.
    """
    o1 = np.asarray(o1_xy, dtype=np.float64).reshape(2)
    o2 = np.asarray(o2_xy, dtype=np.float64).reshape(2)
    t = np.asarray(target_xy, dtype=np.float64).reshape(2)
    return pair_error_f(
        float(o1[0]),
        float(o1[1]),
        float(o2[0]),
        float(o2[1]),
        float(t[0]),
        float(t[1]),
        float(sigma_bearing_rad),
        float(sigma_baseline_m),
    )


def pair_error_f(  # noqa: PLR0917 - eight plain floats, the hot path of pair ranking and localisation
    x1: float, y1: float, x2: float, y2: float, tx: float, ty: float, sigma_bearing_rad: float, sigma_baseline_m: float
) -> float:
    """:func:`pair_position_error` on plain floats (no array conversion: the per-candidate hot path)."""
    v1x, v1y, v2x, v2y = tx - x1, ty - y1, tx - x2, ty - y2
    d1, d2 = math.hypot(v1x, v1y), math.hypot(v2x, v2y)
    b = math.hypot(x2 - x1, y2 - y1)
    if d1 <= 0 or d2 <= 0 or b <= 0:
        return MAX_ERROR_M
    sin0 = abs(v1x * v2y - v1y * v2x) / (d1 * d2)
    if sin0 * MAX_ERROR_M <= sigma_bearing_rad * math.hypot(d1, d2):
        return MAX_ERROR_M
    var = (sigma_bearing_rad * math.hypot(d1, d2) / sin0) ** 2 + (d1 * sigma_baseline_m / b) ** 2
    return min(math.sqrt(var), MAX_ERROR_M)


def pair_position_errors(
    o1_xy: npt.ArrayLike,
    o2_xy: npt.ArrayLike,
    target_xy: npt.ArrayLike,
    sigma_bearing_rad: npt.ArrayLike,
    sigma_baseline_m: npt.ArrayLike = 0.0,
) -> FloatArray:
    """:func:`pair_position_error` for N pairs in one pass: (N, 2) origins, a (2,) or (N, 2) target, (N,) or
    scalar sigmas; returns (N,) errors, equal to the scalar function's up to rounding."""
    o1 = np.asarray(o1_xy, dtype=np.float64).reshape(-1, 2)
    o2 = np.asarray(o2_xy, dtype=np.float64).reshape(-1, 2)
    t = np.asarray(target_xy, dtype=np.float64)
    t = t.reshape(-1, 2)
    sigma = np.asarray(sigma_bearing_rad, dtype=np.float64)
    sigma_b = np.asarray(sigma_baseline_m, dtype=np.float64)
    v1, v2 = t - o1, t - o2
    d1 = np.hypot(v1[:, 0], v1[:, 1])
    d2 = np.hypot(v2[:, 0], v2[:, 1])
    b = np.hypot(o2[:, 0] - o1[:, 0], o2[:, 1] - o1[:, 1])
    dd = np.hypot(d1, d2)
    with np.errstate(divide="ignore", invalid="ignore"):
        sin0 = np.abs(v1[:, 0] * v2[:, 1] - v1[:, 1] * v2[:, 0]) / (d1 * d2)
        var = (sigma * dd / sin0) ** 2 + (d1 * sigma_b / b) ** 2
        out = np.minimum(np.sqrt(var), MAX_ERROR_M)
    degenerate = (d1 <= 0) | (d2 <= 0) | (b <= 0) | (sin0 * MAX_ERROR_M <= sigma * dd)
    return np.asarray(np.where(degenerate, MAX_ERROR_M, out), dtype=np.float64)
