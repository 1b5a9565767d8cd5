"""Floor-plane stereo geometry of the paper: Eqs. (1)-(3) and N-ray intersection.

Conventions: positions are world floor coordinates (m); bearings are world
azimuths (rad, counter-clockwise from +x). For a pair, O1 and O2 are the two
viewpoints, T the target, B = |O1 O2|, and phi1, phi2, phi0 the inner angles of
the triangle O1 O2 T at O1, O2 and T (paper, Fig. 2a).

* Eq. (1), triangulation: D1 = B sin phi2 / sin(phi1 + phi2), D2 = B sin phi1 / sin(phi1 + phi2).
* Eq. (2), size ratio (target colinear with the baseline):
  D1 = B w2 cos phi2 cos phi1 / (w1 cos phi1 + w2 cos phi2), and symmetrically D2.
* Eq. (3), mutual calibration: B = R / sin(alpha / 2), alpha the angle between the
  two occluding rays of the other robot's cylindrical body; its bearing is the mean
  of the two boundary bearings.

The automatic choice between Eq. (1) and Eq. (2) is the crossover of
docs/geometry.md section 3: size ratio is the better estimate iff the target's
perpendicular offset h from the baseline line satisfies h < W * sigma_phi / sigma_w,
with W the target's width.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
import numpy.typing as npt

from common.angles import angle_diff, wrap_angle
from common.arrays import FloatArray
from common.errors import GeometryError

__all__ = [
    "MAX_SIZE_RATIO_OFFSET_RAD",
    "PairFix",
    "RayFix",
    "baseline_exact",
    "baseline_from_alpha",
    "intersect_rays",
    "localize_pair",
    "sighting_bearing",
    "size_ratio",
    "triangulate",
]


MAX_SIZE_RATIO_OFFSET_RAD = math.radians(10.0)
"""Eq. (2) is only considered when the target is within this angle of the baseline line
(as seen from both cameras): the size-ratio formula has a bias ~h^2/(2 D2) off the line."""

MIN_SIN = 1e-12
"""Rays whose converging angle has a sine below this are parallel: Eq. (1) has no solution."""
MIN_SIZE_RATIO_DEN = 1e-15
"""Eq. (2) is singular when w1 cos phi1 + w2 cos phi2 is below this."""
MIN_RAYS = 2
"""An intersection needs at least two rays."""
MAX_RAYS_COND = 1e10
"""Rays whose normal equations are worse conditioned than this are (nearly) parallel."""
AT_CAMERA_M2 = 1e-18
"""A point closer than this (squared, m^2) to a ray's origin has no bearing from it."""
CONVERGED_M = 1e-10
"""The Gauss-Newton refinement stops when its step is below this (m)."""


def _triangulate_f(b: float, p1: float, p2: float) -> tuple[float, float]:
    """Eq. (1) on plain floats (the scalar branch of :func:`triangulate`; numpy on 0-d arrays costs ~10x)."""
    s0 = math.sin(p1 + p2)
    if not (p1 >= 0 and p2 >= 0 and p1 + p2 < math.pi and s0 > MIN_SIN and b > 0):
        raise GeometryError(
            f"triangulation needs converging rays: phi1={p1:.6g}, phi2={p2:.6g} rad "
            f"(expected >= 0 with phi1 + phi2 < pi), B={b:.6g} m (expected > 0)"
        )
    return b * math.sin(p2) / s0, b * math.sin(p1) / s0


def triangulate(b_m: Any, phi1_rad: Any, phi2_rad: Any) -> tuple[Any, Any]:
    """Eq. (1): distances (D1, D2) from the baseline and the two inner angles.

    Scalars return floats and raise :class:`GeometryError` when the rays do not
    converge (phi1, phi2 >= 0 and phi1 + phi2 < pi required, with a non-zero
    angle at T); arrays return NaN there instead.
    """
    if np.ndim(b_m) == 0 and np.ndim(phi1_rad) == 0 and np.ndim(phi2_rad) == 0:
        return _triangulate_f(float(b_m), float(phi1_rad), float(phi2_rad))
    b = np.asarray(b_m, dtype=np.float64)
    p1 = np.asarray(phi1_rad, dtype=np.float64)
    p2 = np.asarray(phi2_rad, dtype=np.float64)
    s0 = np.sin(p1 + p2)  # = sin(phi0), phi0 = pi - phi1 - phi2
    ok = (p1 >= 0) & (p2 >= 0) & (p1 + p2 < math.pi) & (s0 > MIN_SIN) & (b > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        d1 = np.where(ok, b * np.sin(p2) / s0, np.nan)
        d2 = np.where(ok, b * np.sin(p1) / s0, np.nan)
    return d1, d2


def size_ratio(b_m: float, w1: float, w2: float, cos_phi1: float, cos_phi2: float) -> tuple[float, float]:
    """Eq. (2): distances (D1, D2) of a target colinear with the baseline from its two image sizes.

    ``w1``, ``w2`` are sizes proportional to 1/distance (widths or heights, in
    pixels or tan/sin of half-angles); the cosines only give signs: (+1, +1)
    target between the robots, (+1, -1) beyond O2, (-1, +1) beyond O1.

    Raises:
        GeometryError: the sizes are not positive, or the combination has no
            positive solution (e.g. beyond O2 but w2 <= w1).
    """
    if not (w1 > 0 and w2 > 0 and b_m > 0):
        raise GeometryError(f"size ratio needs w1, w2, B > 0, got w1={w1}, w2={w2}, B={b_m}")
    den = w1 * cos_phi1 + w2 * cos_phi2
    if abs(den) < MIN_SIZE_RATIO_DEN:
        raise GeometryError(f"size ratio is singular: w1 cos phi1 + w2 cos phi2 = 0 (w1={w1}, w2={w2})")
    d1 = b_m * w2 * cos_phi2 / den * cos_phi1
    d2 = b_m * w1 * cos_phi1 / den * cos_phi2
    if not (d1 > 0 and d2 > 0):
        raise GeometryError(
            f"size ratio has no positive solution: D1={d1:.4g}, D2={d2:.4g} m "
            f"(w1={w1:.4g}, w2={w2:.4g}, cos phi1={cos_phi1:+.0f}, cos phi2={cos_phi2:+.0f})"
        )
    return float(d1), float(d2)


def baseline_from_alpha(alpha_rad: float, radius_m: float) -> float:
    """Eq. (3): distance to the axis of a cylinder of radius R subtending alpha: B = R / sin(alpha / 2)."""
    if not (0.0 < alpha_rad < math.pi) or not radius_m > 0:
        raise GeometryError(f"Eq. (3) needs 0 < alpha < pi and R > 0, got alpha={alpha_rad} rad, R={radius_m} m")
    return radius_m / math.sin(alpha_rad / 2.0)


def baseline_exact(left_rad: float, right_rad: float, radius_m: float) -> float:
    """Eq. (3) from the two occluding-boundary bearings (tangent rays), robust to the +-pi wrap.

    The two boundary rays are tangent to the cylinder, so sin(alpha/2) = R / B
    holds exactly (no small-angle approximation: B ~ 2R/alpha is only its limit).
    The boundaries may be given in either order.
    """
    alpha = abs(wrap_angle(left_rad - right_rad))
    return baseline_from_alpha(alpha, radius_m)


def sighting_bearing(left_rad: float, right_rad: float) -> float:
    """Bearing of the cylinder's axis: the circular mean of the two boundary bearings (Eq. 3's beta)."""
    return float(wrap_angle(right_rad + wrap_angle(left_rad - right_rad) / 2.0))


# --------------------------------------------------------------------------------------------------
# N rays
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True, eq=False)
class RayFix:
    """Least-squares intersection of N floor bearing rays."""

    xy: FloatArray
    """(2,) the point (m)."""
    cov: FloatArray
    """(2, 2) covariance (m^2) from the bearing sigmas, first order."""
    residual_rms: float
    """RMS of the bearing residuals divided by their sigmas (~1 when consistent)."""


def intersect_rays(origins_xy: npt.ArrayLike, bearings_rad: npt.ArrayLike, sigmas_rad: npt.ArrayLike) -> RayFix:
    """Maximum-likelihood point seen from N >= 2 origins at the given bearings (Gaussian bearing noise).

    Linear least squares on the perpendicular distances gives a start; Gauss-Newton
    on the bearing residuals (each weighted by 1/sigma) refines it, and the
    covariance is (J^T W J)^-1 at the solution.

    Raises:
        GeometryError: fewer than 2 rays, bad shapes or sigmas, (near-)parallel rays,
            or a solution behind one of the cameras (the rays do not converge).
    """
    o = np.asarray(origins_xy, dtype=np.float64).reshape(-1, 2)
    th = np.asarray(bearings_rad, dtype=np.float64).ravel()
    sg = np.broadcast_to(np.asarray(sigmas_rad, dtype=np.float64), th.shape).astype(np.float64)
    n = o.shape[0]
    if n < MIN_RAYS or th.shape != (n,):
        raise GeometryError(f"need >= 2 rays with one bearing each, got {n} origins and {th.size} bearings")
    if not (np.all(np.isfinite(o)) and np.all(np.isfinite(th)) and np.all(sg > 0)):
        raise GeometryError("ray origins and bearings must be finite and sigmas > 0")
    d = np.column_stack([np.cos(th), np.sin(th)])
    nrm = np.column_stack([-d[:, 1], d[:, 0]])
    w = 1.0 / sg**2
    a = (nrm * w[:, None]).T @ nrm
    rhs = (nrm * w[:, None]).T @ np.einsum("ij,ij->i", nrm, o)
    if np.linalg.cond(a) > MAX_RAYS_COND:
        raise GeometryError("the rays are (nearly) parallel: no unique intersection")
    x = np.linalg.solve(a, rhs)
    jtj = a
    for _ in range(10):
        diff = x - o
        r2 = np.einsum("ij,ij->i", diff, diff)
        if np.any(r2 < AT_CAMERA_M2):
            raise GeometryError("the intersection coincides with a camera position")
        res = wrap_angle(np.arctan2(diff[:, 1], diff[:, 0]) - th) / sg
        jac = np.column_stack([-diff[:, 1] / r2, diff[:, 0] / r2]) / sg[:, None]
        jtj = jac.T @ jac
        try:
            step = np.linalg.solve(jtj, -jac.T @ res)
        except np.linalg.LinAlgError as err:
            raise GeometryError("the rays are degenerate at the solution") from err
        x = x + step
        if float(np.hypot(*step)) < CONVERGED_M:
            break
    diff = x - o
    if np.any(np.einsum("ij,ij->i", diff, d) <= 0):
        raise GeometryError("the rays do not converge: the best point lies behind a camera")
    res = wrap_angle(np.arctan2(diff[:, 1], diff[:, 0]) - th) / sg
    r2 = np.einsum("ij,ij->i", diff, diff)
    jac = np.column_stack([-diff[:, 1] / r2, diff[:, 0] / r2]) / sg[:, None]
    cov = np.asarray(np.linalg.inv(jac.T @ jac), dtype=np.float64)
    return RayFix(xy=x, cov=cov, residual_rms=float(np.sqrt(np.mean(res**2))))


# --------------------------------------------------------------------------------------------------
# A camera pair: Eq. (1) or Eq. (2), chosen automatically
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True, eq=False)
class PairFix:
    """A target localised by one camera pair."""

    xy: FloatArray
    """(2,) floor position (m); NaN when ``converges`` is False."""
    d1_m: float
    d2_m: float
    method: Literal["triangulation", "size_ratio"]
    phi0_rad: float
    """Inner angle at the target, pi - |a1| - |a2| clipped to [0, pi] (0 or pi when colinear)."""
    converges: bool
    """False when neither Eq. (1) nor Eq. (2) gives a target in front of both cameras."""


def localize_pair(  # noqa: PLR0917 - positional signature fixed by the team contract
    o1_xy: npt.ArrayLike,
    bearing1_world: float,
    width1_rad: float,
    o2_xy: npt.ArrayLike,
    bearing2_world: float,
    width2_rad: float,
    sigma_bearing_rad: float,
    sigma_width_rad: float,
) -> PairFix:
    """Localise one target from two cameras with known positions (docs/geometry.md sections 3-4).

    Signed inner angles a1 = wrap(theta1 - psi(O1->O2)), a2 = wrap(psi(O2->O1) - theta2);
    the rays converge iff sign a1 = sign a2 and |a1| + |a2| < pi, then Eq. (1).
    Near colinearity, Eq. (2) (size ratio) is used iff h < W sigma_phi / sigma_w,
    i.e. (h / W) = sin(delta_k) / (2 tan(w_k / 2)) averaged over both views, with
    delta_k the angular offset from the baseline line, and only within
    :data:`MAX_SIZE_RATIO_OFFSET_RAD` of it. Widths enter Eq. (2) as sin(w/2),
    exact for a cylindrical body (sin(w/2) = r/D).
    """
    # Plain floats throughout: this runs for every candidate pair of every person on every tick.
    p1 = np.asarray(o1_xy, dtype=np.float64).reshape(2)
    p2 = np.asarray(o2_xy, dtype=np.float64).reshape(2)
    x1, y1, x2, y2 = float(p1[0]), float(p1[1]), float(p2[0]), float(p2[1])
    bearing1_world, bearing2_world = float(bearing1_world), float(bearing2_world)
    bx, by = x2 - x1, y2 - y1
    b = math.hypot(bx, by)
    if b <= 0:
        raise GeometryError("the two cameras are at the same position: baseline B = 0")
    psi12 = math.atan2(by, bx)
    a1 = angle_diff(bearing1_world, psi12)
    a2 = angle_diff(psi12 + math.pi, bearing2_world)
    abs1, abs2 = abs(a1), abs(a2)
    phi0 = min(max(math.pi - abs1 - abs2, 0.0), math.pi)

    # Eq. (2) candidate: angular offsets from the baseline line and signs from the cosines.
    delta1 = min(abs1, math.pi - abs1)
    delta2 = min(abs2, math.pi - abs2)
    c1 = 1.0 if abs1 < math.pi / 2 else -1.0
    c2 = 1.0 if abs2 < math.pi / 2 else -1.0
    use_size = False
    if max(delta1, delta2) < MAX_SIZE_RATIO_OFFSET_RAD and (c1 > 0 or c2 > 0) and width1_rad > 0 and width2_rad > 0:
        h_over_w = 0.5 * (
            math.sin(delta1) / (2 * math.tan(width1_rad / 2)) + math.sin(delta2) / (2 * math.tan(width2_rad / 2))
        )
        threshold = math.inf if sigma_width_rad <= 0 else sigma_bearing_rad / sigma_width_rad
        use_size = h_over_w < threshold
    if use_size:
        try:
            d1, d2 = size_ratio(b, math.sin(width1_rad / 2), math.sin(width2_rad / 2), c1, c2)
        except GeometryError:
            use_size = False
        else:
            xy = np.array([x1 + d1 * math.cos(bearing1_world), y1 + d1 * math.sin(bearing1_world)])
            return PairFix(xy=xy, d1_m=d1, d2_m=d2, method="size_ratio", phi0_rad=phi0, converges=True)

    converges = (a1 > 0) == (a2 > 0) and a1 != 0 and a2 != 0 and abs1 + abs2 < math.pi
    if not converges:
        nan2 = np.full(2, np.nan)
        return PairFix(xy=nan2, d1_m=math.nan, d2_m=math.nan, method="triangulation", phi0_rad=phi0, converges=False)
    d1, d2 = _triangulate_f(b, abs1, abs2)
    xy = np.array([x1 + d1 * math.cos(bearing1_world), y1 + d1 * math.sin(bearing1_world)])
    return PairFix(xy=xy, d1_m=d1, d2_m=d2, method="triangulation", phi0_rad=phi0, converges=True)
