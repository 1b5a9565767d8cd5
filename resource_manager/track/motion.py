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

from common.angles import wrap_angle
from common.arrays import FloatArray

__all__ = [
    "LineObservation",
    "MotionModel",
    "Observation",
    "ObservationBatch",
    "core_share",
    "predict",
    "predict_many",
    "update",
    "update_many",
    "update_without_each",
]

IEKF_ITERATIONS = 4
"""Gauss-Newton steps of the update (each re-linearises the bearings at the new estimate)."""
MIN_RANGE_M = 0.3
"""Closer to a camera than this a bearing says nothing (the person stands on the lens)."""

CONVERGED_STEP_M = 1e-4
"""A track whose iterated update moved its position less than this (m) has converged: its iterations stop."""


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


def predict_many(x: FloatArray, p: FloatArray, dt_s: FloatArray, model: MotionModel) -> tuple[FloatArray, FloatArray]:
    """:func:`predict` of many tracks at once: states ``x`` (k, 4), covariances ``p`` (k, 4, 4), each ``dt_s``
    (k,) later (tracks predicted to one instant share one transition)."""
    x_new, p_new = x.copy(), p.copy()
    for dt in np.unique(dt_s[dt_s > 0]):
        rows = dt_s == dt
        f, q = model.transition(float(dt))
        x_new[rows] = x[rows] @ f.T
        p_new[rows] = f @ p[rows] @ f.T + q
    return x_new, p_new


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
class ObservationBatch:
    """The observations of many tracks at once, padded to the most views (and lines) any of them has.

    Row ``k`` holds track ``k``'s observations; slots beyond its own are marked invalid and weigh nothing.
    Building the arrays once per tick and stepping every track's filter together costs a few array operations per
    tick instead of a few dozen per track.
    """

    origin: FloatArray
    """(k, v, 2) camera positions."""
    bearing_rad: FloatArray
    """(k, v) measured bearings."""
    bearing_var: FloatArray
    """(k, v) their variances (rad²)."""
    range_m: FloatArray
    """(k, v) floor distances from the feet (0 where there is none)."""
    range_var: FloatArray
    """(k, v) their variances (m²; 1 where there is none)."""
    has_range: npt.NDArray[np.bool_]
    """(k, v) which observations have a floor distance."""
    valid: npt.NDArray[np.bool_]
    """(k, v) which slots hold an observation."""
    lines_dir: FloatArray
    """(k, l, 2) unit directions of the line observations."""
    lines_value: FloatArray
    """(k, l)"""
    lines_var: FloatArray
    """(k, l) (1 where there is none)."""
    lines_valid: npt.NDArray[np.bool_]
    """(k, l) which slots hold a line observation."""

    @staticmethod
    def of(obs: list[list[Observation]], lines: list[list[LineObservation]] | None = None) -> ObservationBatch:
        """The batch of per-track lists of observations (and lines)."""
        k = len(obs)
        lines = lines or [[] for _ in obs]
        nv = max((len(o) for o in obs), default=0)
        nl = max((len(ln) for ln in lines), default=0)
        rows = np.zeros((k, nv, 6))
        rows[:, :, 3] = rows[:, :, 5] = 1.0
        rows[:, :, 4] = math.nan
        valid = np.zeros((k, nv), dtype=bool)
        for i, track_obs in enumerate(obs):
            for j, ob in enumerate(track_obs):
                rows[i, j] = (*ob.origin_xy, ob.bearing_rad, ob.bearing_var, ob.range_m, ob.range_var)
                valid[i, j] = True
        lrows = np.zeros((k, nl, 4))
        lrows[:, :, 3] = 1.0
        lvalid = np.zeros((k, nl), dtype=bool)
        for i, track_lines in enumerate(lines):
            for j, ln in enumerate(track_lines):
                lrows[i, j] = (*ln.direction, ln.value, ln.var)
                lvalid[i, j] = True
        return ObservationBatch.padded(rows, valid, lrows, lvalid)

    @staticmethod
    def padded(
        rows: FloatArray, valid: npt.NDArray[np.bool_], lines: FloatArray, lines_valid: npt.NDArray[np.bool_]
    ) -> ObservationBatch:
        """The batch of ``rows`` (k, v, 6): origin x, y, bearing, its variance, range (NaN: none), its variance;
        ``lines`` (k, l, 4): direction x, y, value, variance; invalid slots may hold anything finite or NaN."""
        has = valid & np.isfinite(rows[:, :, 4])
        lines_valid = lines_valid.copy()
        return ObservationBatch(
            origin=np.where(valid[:, :, None], rows[:, :, :2], 0.0),
            bearing_rad=np.where(valid, rows[:, :, 2], 0.0),
            bearing_var=np.where(valid, rows[:, :, 3], 1.0),
            range_m=np.where(has, rows[:, :, 4], 0.0),
            range_var=np.where(has, rows[:, :, 5], 1.0),
            has_range=has,
            valid=valid,
            lines_dir=np.where(lines_valid[:, :, None], lines[:, :, :2], 0.0),
            lines_value=np.where(lines_valid, lines[:, :, 2], 0.0),
            lines_var=np.where(lines_valid, lines[:, :, 3], 1.0),
            lines_valid=lines_valid,
        )


@dataclass(frozen=True, slots=True)
class _Rows:
    """A batch's observations as rows of one kind after the other: every slot's bearing, then its floor distance
    (weightless where there is none), each row with its camera."""

    origin: FloatArray
    """(k, v, 2) the cameras (of both kinds of rows: the first ``v`` bearings, the next ``v`` distances)."""
    z: FloatArray
    """(k, 2v) measured values."""
    var: FloatArray
    """(k, 2v) their variances."""
    info: FloatArray
    """(k, 2v) their information (1 / variance; 0 in the rows without a measurement)."""
    has_range: npt.NDArray[np.bool_]
    """(k, v) which slots have a floor distance."""
    valid: npt.NDArray[np.bool_]
    """(k, v) which slots hold an observation."""

    @staticmethod
    def of(batch: ObservationBatch) -> _Rows:
        var = np.concatenate([batch.bearing_var, batch.range_var], axis=1)
        used = np.concatenate([batch.valid, batch.has_range], axis=1)
        return _Rows(
            batch.origin,
            np.concatenate([batch.bearing_rad, batch.range_m], axis=1),
            var,
            np.where(used, 1.0 / var, 0.0),
            batch.has_range,
            batch.valid,
        )

    def predicted(self, xy: FloatArray) -> tuple[FloatArray, FloatArray]:
        """(h, H) at positions ``xy`` (k, 2): (k, 2v) predicted bearings then distances, and (k, 2v, 2) their
        gradients in position."""
        d = xy[:, None, :] - self.origin
        dx, dy = d[:, :, 0], d[:, :, 1]
        r2 = np.maximum(dx * dx + dy * dy, MIN_RANGE_M**2)
        r = np.sqrt(r2)
        v = dx.shape[1]
        jac = np.empty((dx.shape[0], 2 * v, 2))
        jac[:, :v, 0], jac[:, :v, 1] = -dy / r2, dx / r2
        jac[:, v:] = d / r[:, :, None]
        return np.concatenate([np.arctan2(dy, dx), r], axis=1), jac


def _outer_sum(w: FloatArray, jac: FloatArray) -> FloatArray:
    """(k, 2, 2) Σ_rows w Jᵀ J of each track's rows (``w`` (k, r), ``jac`` (k, r, 2))."""
    return np.asarray(np.swapaxes(jac * w[:, :, None], 1, 2) @ jac, dtype=np.float64)


def quadratic_form(a: FloatArray, p: FloatArray, b: FloatArray) -> FloatArray:
    """aᵀ P b of 2-vectors ``a``, ``b`` (..., 2) and 2x2 matrices ``p`` (..., 2, 2), broadcast (elementwise
    arithmetic: cheaper than ``einsum`` on the small arrays of one tick)."""
    a0, a1, b0, b1 = a[..., 0], a[..., 1], b[..., 0], b[..., 1]
    return np.asarray(
        a0 * (p[..., 0, 0] * b0 + p[..., 0, 1] * b1) + a1 * (p[..., 1, 0] * b0 + p[..., 1, 1] * b1), dtype=np.float64
    )


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
    ``lines``: measurements along one direction each (reweighed the same way).

    One track's case of :func:`update_many`.

    Returns:
        (x, P, weight of each observation in [0, 1]; 1 without ``outlier``).
    """
    if not obs:
        return x, p, np.ones(0)
    batch = ObservationBatch.of([obs], [lines or []])
    xs, ps, weights = update_many(x[None, :], p[None, :, :], batch, outlier)
    return xs[0], ps[0], weights[0]


def update_many(
    x: FloatArray,
    p: FloatArray,
    batch: ObservationBatch,
    outlier: tuple[float, float] | None = None,
    iterations: int = IEKF_ITERATIONS,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """:func:`update` of many tracks at once: states ``x`` (k, 4), covariances ``p`` (k, 4, 4), each track with
    its row of ``batch``.

    ``iterations``: at most this many Gauss-Newton steps (the first is the plain EKF update).

    The steps are taken in information form (the measurement noise is diagonal and the state has four
    dimensions): each is a 4x4 solve per track whatever the number of views. Each track stops iterating once its
    step moves it less than 0.1 mm, as it would on its own.

    Returns:
        (x (k, 4), P (k, 4, 4), weight (k, v) of each observation in [0, 1]; 1 without ``outlier``, 0 in the
        slots without one).
    """
    k, nv = batch.valid.shape
    if k == 0:
        return x, p, np.zeros((0, nv))
    xi, p_new, resp, _ = _iterate(
        x, p, batch, outlier, iterations=iterations, info_prior=np.linalg.inv(p), rows=_Rows.of(batch)
    )
    return xi, p_new, resp


def _iterate(
    x: FloatArray,
    p: FloatArray,
    batch: ObservationBatch,
    outlier: tuple[float, float] | None,
    *,
    iterations: int,
    info_prior: npt.NDArray[np.floating],
    rows: _Rows,
) -> tuple[FloatArray, FloatArray, FloatArray, tuple[FloatArray, FloatArray]]:
    """:func:`update_many`'s steps, given the prior's information ``info_prior`` (the inverse of ``p``) and the
    batch's ``rows``; also the rows' predictions and Jacobians at the estimate (:meth:`_Rows.predicted`)."""
    k, nv = batch.valid.shape
    h, jac = rows.predicted(x[:, :2])
    resp = batch.valid.astype(np.float64)
    # The lines are linear in the position: their innovations against the prediction do not change.
    info_line = np.where(batch.lines_valid, 1.0 / batch.lines_var, 0.0)
    nu_line = batch.lines_value - np.einsum("kli,ki->kl", batch.lines_dir, x[:, :2])
    resp_line = batch.lines_valid.astype(np.float64)
    if outlier is not None:  # first judged against the prediction, with its uncertainty
        resp = _responsibilities(h, jac, p, rows, outlier)
        resp_line = _line_responsibilities(batch, x[:, :2], p, outlier)
    xi = x.copy()
    p_new = p
    active = np.ones(k, dtype=bool)
    # Without lines (the usual case) their information and gradient are zeros: adding them changes nothing.
    has_lines = batch.lines_valid.size > 0
    for _ in range(iterations):
        # An outlier says nothing about where the person is (another person's blob): weight by resp alone.
        w = np.concatenate([resp, resp], axis=1) * rows.info
        info = info_prior.copy()
        nu = rows.z - h - (jac @ (x - xi)[:, :2, None])[:, :, 0]
        nu[:, :nv] = wrap_angle(nu[:, :nv])
        gain, grad = _outer_sum(w, jac), _weighted_sum(w * nu, jac)
        if has_lines:
            w_line = resp_line * info_line
            gain = gain + _outer_sum(w_line, batch.lines_dir)
            grad = _weighted_sum(w_line * nu_line, batch.lines_dir) + grad
        info[:, :2, :2] += gain
        p_step = np.linalg.inv(info)
        step = x + (p_step[:, :, :2] @ grad[:, :, None])[:, :, 0]
        moved = np.hypot(step[:, 0] - xi[:, 0], step[:, 1] - xi[:, 1])
        xi = np.where(active[:, None], step, xi)
        p_new = np.where(active[:, None, None], p_step, p_new)
        last = not (active & (moved >= CONVERGED_STEP_M)).any()
        h, jac = rows.predicted(xi[:, :2])
        if outlier is not None:
            resp = np.where(active[:, None], _responsibilities(h, jac, p_new, rows, outlier), resp)
            resp_line = np.where(active[:, None], _line_responsibilities(batch, xi[:, :2], p_new, outlier), resp_line)
        active &= moved >= CONVERGED_STEP_M
        if last:
            break
    return xi, 0.5 * (p_new + np.swapaxes(p_new, 1, 2)), resp, (h, jac)


def update_without_each(
    x: FloatArray,
    p: FloatArray,
    batch: ObservationBatch,
    outlier: tuple[float, float] | None = None,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """:func:`update_many` of every track, and of every track without each of its observations in turn.

    Each left-out update is the full update's information with that slot's taken out again, and one Gauss-Newton
    step from the full estimate on what is left: one 4x4 solve per slot instead of an iterated update per slot.
    The other slots keep the weights (outlier responsibilities) the full update gave them. The batch's lines stay
    in every left-out update.

    Returns:
        (x (k, 4), P (k, 4, 4) of the full updates; x (k, v, 4), P (k, v, 4, 4) without slot v; the slots without
        an observation hold the full update).
    """
    k, nv = batch.valid.shape
    if k == 0 or nv == 0:
        xi, p_full, _ = update_many(x, p, batch, outlier)
        return xi, p_full, np.repeat(xi[:, None], nv, axis=1), np.repeat(p_full[:, None], nv, axis=1)
    info_prior, rows = np.linalg.inv(p), _Rows.of(batch)
    xi, p_full, resp, (h, jac) = _iterate(
        x, p, batch, outlier, iterations=IEKF_ITERATIONS, info_prior=info_prior, rows=rows
    )
    w = np.concatenate([resp, resp], axis=1) * rows.info
    nu = rows.z - h
    nu[:, :nv] = wrap_angle(nu[:, :nv])
    info = info_prior.copy()
    gain, pull = _outer_sum(w, jac), _weighted_sum(w * nu, jac)
    if batch.lines_valid.size:  # no lines (the usual case): their zeros left out, as in _iterate
        w_line = (
            batch.lines_valid / batch.lines_var
            if outlier is None
            else _line_responsibilities(batch, xi[:, :2], p_full, outlier) / batch.lines_var
        )
        nu_line = batch.lines_value - np.einsum("kli,ki->kl", batch.lines_dir, xi[:, :2])
        gain = gain + _outer_sum(w_line, batch.lines_dir)
        pull = _weighted_sum(w_line * nu_line, batch.lines_dir) + pull
    info[:, :2, :2] += gain
    # The gradient of the full update's cost at its estimate (0 where it converged), and each slot's share of it.
    grad = (info_prior @ (xi - x)[:, :, None])[:, :, 0]
    grad[:, :2] -= pull
    wb, wr = w[:, :nv, None, None], w[:, nv:, None, None]
    jb, jr = jac[:, :nv], jac[:, nv:]
    slot_info = wb * jb[..., :, None] * jb[..., None, :] + wr * jr[..., :, None] * jr[..., None, :]
    slot_grad = (w[:, :nv, None] * nu[:, :nv, None]) * jb + (w[:, nv:, None] * nu[:, nv:, None]) * jr
    info_out = np.repeat(info[:, None], nv, axis=1)
    info_out[:, :, :2, :2] -= slot_info
    grad_out = np.repeat(grad[:, None], nv, axis=1)
    grad_out[:, :, :2] += slot_grad
    p_out = np.linalg.inv(info_out)
    x_out = xi[:, None] - (p_out @ grad_out[..., None])[..., 0]
    return xi, p_full, x_out, 0.5 * (p_out + np.swapaxes(p_out, -1, -2))


def _weighted_sum(w: FloatArray, jac: FloatArray) -> FloatArray:
    """(k, 2) Σ_rows w J of each track's rows."""
    return np.einsum("kr,kri->ki", w, jac)


def _line_responsibilities(
    batch: ObservationBatch, xy: FloatArray, p: FloatArray, outlier: tuple[float, float]
) -> FloatArray:
    """(k, l) posterior probability of each line's core (not outlier) component at the estimate ``xy`` with its
    covariance ``p``: a width ratio is as fallible as a bearing (a blob cut by someone in front, two people
    merged into one), so a line the views contradict is weighed down like a view."""
    if not batch.lines_valid.size:  # no lines (the usual case: no two views near colinear): nothing to weigh
        return np.zeros(batch.lines_valid.shape)
    eps, scale = outlier
    d = batch.lines_dir
    var = batch.lines_var + quadratic_form(d, p[:, None, :2, :2], d)
    nu = batch.lines_value - np.einsum("kli,ki->kl", d, xy)
    d2 = nu**2 / var
    core = (1.0 - eps) * np.exp(-0.5 * d2)
    wide = eps / scale * np.exp(-0.5 * d2 / scale**2)
    return np.asarray(np.where(batch.lines_valid, core / np.maximum(core + wide, 1e-300), 0.0), dtype=np.float64)


def _responsibilities(
    h: FloatArray, jac: FloatArray, p: FloatArray, rows: _Rows, outlier: tuple[float, float]
) -> FloatArray:
    """(k, v) posterior probability of each observation's core (not outlier) component, from its residual at the
    estimate ``h``, ``jac`` were predicted at and its variance there (the measurement's plus the estimate's,
    ``p``); the lines left out."""
    nv = h.shape[1] // 2
    var = rows.var + np.einsum("kri,kri->kr", jac @ p[:, :2, :2], jac)
    nu = rows.z - h
    nu[:, :nv] = wrap_angle(nu[:, :nv])
    terms = nu**2 / var
    has = rows.has_range
    d2 = terms[:, :nv] + np.where(has, terms[:, nv:], 0.0)
    return np.asarray(np.where(rows.valid, core_share(d2, np.where(has, 2, 1), outlier), 0.0), dtype=np.float64)


def core_share(d2: FloatArray, dim: npt.ArrayLike, outlier: tuple[float, float]) -> FloatArray:
    """Posterior probability that a residual of squared Mahalanobis distance ``d2`` (dimension ``dim``) is the
    Gaussian core's, not the outlier part's (``outlier``: its probability, and how many times wider it is)."""
    eps, scale = outlier
    core = (1.0 - eps) * np.exp(-0.5 * d2)
    wide = eps / np.power(scale, dim) * np.exp(-0.5 * d2 / scale**2)
    return np.asarray(core / np.maximum(core + wide, 1e-300), dtype=np.float64)
