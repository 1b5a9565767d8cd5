"""The motion model and the filter: where a person will be, and what the views say about where they are.

**Motion.** Each floor axis is an integrated Ornstein-Uhlenbeck process: the velocity decays towards 0 with
time constant τ (``turn_time_s``) and is driven by white noise that keeps its stationary spread at σ_v
(``speed_sigma_mps``). A person seen walking is predicted to keep walking for about τ; a person nobody sees is
predicted to stop near where they were last seen, with an uncertainty that grows like √t rather than t³ (the
constant-velocity model's). With a = e^{-Δt/τ} and q = 2σ_v²/τ, per axis::

    x' = x + τ(1 - a) v          v' = a v
    Q_vv = σ_v² (1 - a²)
    Q_xv = q τ² [(1 - a) - (1 - a²)/2]
    Q_xx = q τ² [Δt - 2τ(1 - a) + τ(1 - a²)/2]

**Update.** A view contributes its bearing θ = atan2(y - c_y, x - c_x) and, where it sees the feet, the floor
distance D = |p - c|, each with its own variance. All views assigned to a track update it at once, by
Gauss-Newton iterations of the extended Kalman filter (an iterated EKF): bearings are non-linear in the
position, and one wide prior (a new or long-hidden person) is pulled far by the first linearisation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

__all__ = ["LineObservation", "MotionModel", "Observation", "predict", "update"]

FloatArray = npt.NDArray[np.float64]
IEKF_ITERATIONS = 4
"""Gauss-Newton steps of the update (each re-linearises the bearings at the new estimate)."""
MIN_RANGE_M = 0.3
"""Closer to a camera than this a bearing says nothing (the person stands on the lens)."""


@dataclass(frozen=True, slots=True)
class MotionModel:
    speed_sigma_mps: float
    turn_time_s: float

    def transition(self, dt_s: float) -> tuple[FloatArray, FloatArray]:
        """(F, Q) for the state (x, y, vx, vy) over ``dt_s``."""
        tau = self.turn_time_s
        a = math.exp(-dt_s / tau)
        q = 2.0 * self.speed_sigma_mps**2 / tau
        qvv = self.speed_sigma_mps**2 * (1.0 - a * a)
        qxv = q * tau * tau * ((1.0 - a) - 0.5 * (1.0 - a * a))
        qxx = q * tau * tau * (dt_s - 2.0 * tau * (1.0 - a) + 0.5 * tau * (1.0 - a * a))
        f = np.eye(4)
        f[0, 2] = f[1, 3] = tau * (1.0 - a)
        f[2, 2] = f[3, 3] = a
        qm = np.zeros((4, 4))
        qm[0, 0] = qm[1, 1] = max(qxx, 0.0)
        qm[0, 2] = qm[2, 0] = qm[1, 3] = qm[3, 1] = qxv
        qm[2, 2] = qm[3, 3] = qvv
        return f, qm


def predict(x: FloatArray, p: FloatArray, dt_s: float, model: MotionModel) -> tuple[FloatArray, FloatArray]:
    """State and covariance ``dt_s`` later (unchanged for dt_s <= 0)."""
    if dt_s <= 0:
        return x, p
    f, q = model.transition(dt_s)
    return f @ x, f @ p @ f.T + q


@dataclass(frozen=True, slots=True)
class Observation:
    """What one view says about one person: a bearing and, optionally, a floor distance."""

    origin_xy: tuple[float, float]
    bearing_rad: float
    bearing_var: float
    """Variance of the bearing (rad²), everything included (sensor, pose, body)."""
    range_m: float = math.nan
    """Floor distance from the feet (NaN: none)."""
    range_var: float = math.nan


@dataclass(frozen=True, slots=True)
class LineObservation:
    """A position measured along one floor direction only: ``direction · p = value`` (the size-ratio method's
    fix along a baseline, Eq. 2)."""

    direction: tuple[float, float]
    """Unit vector."""
    value: float
    var: float


@dataclass(frozen=True, slots=True)
class _Stack:
    """Observations stacked as rows: the lines, every view's bearing, then the distances where there are any."""

    origin: FloatArray
    """(no, 2) camera positions."""
    has_range: npt.NDArray[np.bool_]
    lines_dir: FloatArray
    """(nl, 2) unit directions."""
    z: FloatArray
    var: FloatArray
    angle: npt.NDArray[np.bool_]
    """Which rows are angles (residuals wrapped)."""
    rows: npt.NDArray[np.int64]
    """The observation each non-line row comes from."""

    @staticmethod
    def of(obs: list[Observation], lines: list[LineObservation]) -> _Stack:
        o = np.array([(*ob.origin_xy, ob.bearing_rad, ob.bearing_var, ob.range_m, ob.range_var) for ob in obs])
        o = o.reshape(-1, 6)
        has = np.isfinite(o[:, 4])
        nl, no, nr = len(lines), len(obs), int(has.sum())
        return _Stack(
            origin=o[:, :2],
            has_range=has,
            lines_dir=np.array([ln.direction for ln in lines], dtype=np.float64).reshape(-1, 2),
            z=np.concatenate([[ln.value for ln in lines], o[:, 2], o[has, 4]]),
            var=np.concatenate([[ln.var for ln in lines], o[:, 3], o[has, 5]]),
            angle=np.concatenate([np.zeros(nl, bool), np.ones(no, bool), np.zeros(nr, bool)]),
            rows=np.concatenate([np.arange(no), np.flatnonzero(has)]).astype(np.int64),
        )

    def predicted(self, x: FloatArray, with_lines: bool = True) -> tuple[FloatArray, FloatArray]:
        """(h(x), H) of the rows at state ``x`` (without the lines' rows if not ``with_lines``)."""
        d = x[:2] - self.origin
        r2 = np.maximum(d[:, 0] ** 2 + d[:, 1] ** 2, MIN_RANGE_M**2)
        r = np.sqrt(r2)
        has = self.has_range
        parts_h = [np.arctan2(d[:, 1], d[:, 0]), r[has]]
        parts_j = [np.column_stack([-d[:, 1] / r2, d[:, 0] / r2]), d[has] / r[has, None]]
        if with_lines:
            parts_h.insert(0, self.lines_dir @ x[:2])
            parts_j.insert(0, self.lines_dir)
        jac = np.zeros((sum(len(ph) for ph in parts_h), 4))
        jac[:, :2] = np.concatenate(parts_j)
        return np.concatenate(parts_h), jac


def update(
    x: FloatArray,
    p: FloatArray,
    obs: list[Observation],
    outlier: tuple[float, float] | None = None,
    lines: list[LineObservation] | None = None,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The state and covariance after all ``obs`` (iterated EKF), and each observation's weight.

    ``outlier``: (probability, scale) of the observations' outlier component (a badly drawn box, another person's
    blob assigned in a crowd). Each Gauss-Newton step then weighs each observation by the posterior probability
    that it is not an outlier, given its residual and its variance at the current estimate (first the prediction):
    an iteratively reweighted update, so one wrong view does not drag a person seen well by the others.
    ``lines``: measurements along one direction each (taken as they are, not reweighed).

    The steps are taken in information form (the measurement noise is diagonal and the state has four
    dimensions): each is a 4x4 solve whatever the number of views.

    Returns:
        (x, P, weight of each observation in [0, 1]; 1 without ``outlier``).
    """
    if not obs:
        return x, p, np.ones(0)
    lines = lines or []
    st = _Stack.of(obs, lines)
    z, angle = st.z, st.angle
    nl = len(lines)
    info_prior = np.linalg.inv(p)
    resp = np.ones(len(obs))
    if outlier is not None:  # first judged against the prediction, with its uncertainty
        resp = _responsibilities(x, st, nl=nl, outlier=outlier, p=p)
    xi = x.copy()
    p_new = p
    for _ in range(IEKF_ITERATIONS):
        hx, h = st.predicted(xi)
        w = 1.0 / st.var
        if outlier is not None:
            # An outlier says nothing about where the person is (another person's blob): weight by resp alone.
            w = w * np.concatenate([np.ones(nl), resp[st.rows]])
        hw = h.T * w  # Hᵀ W
        p_new = np.asarray(np.linalg.inv(info_prior + hw @ h), dtype=np.float64)
        nu = z - hx - h @ (x - xi)
        nu[angle] = np.remainder(nu[angle] + math.pi, 2.0 * math.pi) - math.pi
        step = x + p_new @ (hw @ nu)
        moved = float(np.hypot(step[0] - xi[0], step[1] - xi[1]))
        xi = step
        if outlier is not None:
            resp = _responsibilities(xi, st, nl=nl, outlier=outlier, p=p_new)
        if moved < 1e-4:
            break
    return xi, 0.5 * (p_new + p_new.T), resp


def _responsibilities(x: FloatArray, st: _Stack, *, nl: int, outlier: tuple[float, float], p: FloatArray) -> FloatArray:
    """Posterior probability of each observation's core (not outlier) component, from its residual at ``x`` and
    its variance there (the measurement's plus the estimate's, ``p``); the lines (first ``nl`` rows) left out."""
    eps, scale = outlier
    hx, h = st.predicted(x, with_lines=False)
    nu = st.z[nl:] - hx
    angle = st.angle[nl:]
    nu[angle] = np.remainder(nu[angle] + math.pi, 2.0 * math.pi) - math.pi
    var = st.var[nl:] + np.einsum("ij,jk,ik->i", h, p, h)
    n = len(st.origin)
    d2 = np.bincount(st.rows, weights=nu**2 / var, minlength=n)
    dims = np.bincount(st.rows, minlength=n).astype(np.float64)
    core = (1.0 - eps) * np.exp(-0.5 * d2)
    wide = eps * np.exp(-0.5 * d2 / scale**2) / scale**dims
    return np.asarray(core / np.maximum(core + wide, 1e-300), dtype=np.float64)
