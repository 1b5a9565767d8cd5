"""Bundle adjustment: the poses of the free cameras, with every person-instant placed where its rays put it.

Residuals, each divided by its sigma so a residual of 1 is one sigma:

* every foot ray's and head ray's perpendicular distance from its point, as two components across the ray
  (metres at the person, sigma the camera's ``point_sigma_m``; a pinhole box's top row gives one, the distance
  off its plane), through Cauchy's robust loss (a wrong pairing, a clutter box hardly pulls);
* each free camera's parameters against its starting guess (the install's, held over every round), with the
  install tolerance as sigma: a weak pull that only fixes what the people cannot (where the site is on the floor
  and which way it faces when no camera is held, a far camera's distance along its line of sight);
* with no camera held, the people's mean height against the prior's (how big the site is).

The unknowns the optimiser sees are the cameras' parameters only (:mod:`.poses`: six for a pinhole camera, four
for a level one). For any poses, each person-instant's ``(x, y, h)`` is the least-squares point of its rays, with
the robust loss's weights (a few reweighting rounds) and the range of people's heights as a prior on ``h``: the
variable-projection form of bundle adjustment, with its Jacobian in closed form (Kaufman's). Put together with
thousands of people as unknowns of their own, scipy's trust region took steps in the people and none in the
cameras; here every step is a camera step, and scipy's ``least_squares`` converges in a few.

A person-instant's height is not pulled towards the others' in the cameras' fit: the same tall person seen at a
thousand instants would count a thousand times, and the fit would tilt the cameras to make them shorter.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares
from scipy.sparse import csr_matrix

from common.arrays import BoolArray, FloatArray, IntArray
from common.pinhole import rotation_from_rvec
from panostereo.calib.associate import RIDGE, Association, HeightPrior, off_ray
from panostereo.calib.observe import CameraRays
from panostereo.calib.poses import CameraPose, pose_offset, rotation_z

__all__ = ["Adjusted", "Tolerance", "adjust", "ray_distances"]

NOT_VERTICAL = 0.9
"""A ray whose z component is below this is crossed with the vertical to build its basis, else with x."""
SMALL_RESIDUAL = 1e-9
"""Below this (sigmas) a residual's robust form is the residual itself."""
MAX_EVALUATIONS = 60
"""Steps per adjustment (each association is followed by one)."""
COST_TOLERANCE = 1e-6
STEP_TOLERANCE = 1e-6
"""An adjustment stops when a step lowers the cost by less than this fraction, or moves the cameras by less than
this fraction of their parameters' scale."""
INNER_ROUNDS = 2
"""Reweighting rounds of each person's fit (the robust loss's weights from the last round's residuals)."""
PARAM_STEP = 0.1
"""The optimiser's scale of each camera parameter, as a fraction of its install tolerance."""


@dataclass(frozen=True, slots=True)
class Tolerance:
    """How far a starting guess may be from the truth: a tape-measure install (the pull towards the guess)."""

    centre_m: float = 1.0
    turn_rad: float = 0.1745


@dataclass(frozen=True, slots=True, eq=False)
class Adjusted:
    poses: list[CameraPose]
    person: FloatArray
    mean_height_m: float
    """The people's median height (m): the next association's and adjustment's prior mean."""
    cost: float
    evaluations: int


def _basis(d: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Two unit vectors across each ray ``d`` (n, 3)."""
    helper = np.where(np.abs(d[:, 2:3]) < NOT_VERTICAL, np.array([[0.0, 0.0, 1.0]]), np.array([[1.0, 0.0, 0.0]]))
    e1 = np.cross(d, helper)
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    return e1, np.cross(d, e1)


def _rotations(poses: list[CameraPose], free: list[int], x: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Every camera's rotation and centre with the free ones moved by their slice of ``x``."""
    rot = np.stack([p.rotation for p in poses])
    cen = np.stack([p.centre_m for p in poses])
    at = 0
    for ci in free:
        p = poses[ci]
        if p.level:
            rot[ci] = p.rotation @ rotation_z(-x[at])
            cen[ci] = p.centre_m + x[at + 1 : at + 4]
        else:
            rot[ci] = rotation_from_rvec(x[at : at + 3]) @ p.rotation
            cen[ci] = p.centre_m + x[at + 3 : at + 6]
        at += p.n_params
    return rot, cen


def ray_distances(
    cams: list[CameraRays], poses: list[CameraPose], assoc: Association, person: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Per membership, the foot and head rays' distances from the person's points (m; NaN where not seen)."""
    rot = np.stack([p.rotation for p in poses])
    cen = np.stack([p.centre_m for p in poses])
    mc = assoc.member_camera
    foot, head, ok_f, ok_h, plane = _members(cams, mc, assoc.member_index)
    p = person[assoc.member_person]
    feet = p.copy()
    feet[:, 2] = 0.0
    out = []
    for pt, d, ok in ((feet, foot, ok_f), (p, head, ok_h)):
        v = np.einsum("mij,mj->mi", rot[mc], pt - cen[mc])
        out.append(np.where(ok, off_ray(d, plane if d is head else np.zeros_like(d), v), np.nan))
    return out[0], out[1]


def _layout(poses: list[CameraPose], free: list[int], tolerance: Tolerance) -> tuple[IntArray, IntArray, FloatArray]:
    """Where each free camera's parameters start in the unknowns (-1: fixed), how many it has, and the inverse
    sigmas of the pull of every parameter towards its starting guess."""
    offset = np.full(len(poses), -1, dtype=np.int64)
    width = np.zeros(len(poses), dtype=np.int64)
    at = 0
    sigma: list[float] = []
    for ci in free:
        offset[ci], width[ci] = at, poses[ci].n_params
        at += poses[ci].n_params
        sigma += [tolerance.turn_rad] * (1 if poses[ci].level else 3) + [tolerance.centre_m] * 3
    return offset, width, 1.0 / np.array(sigma, dtype=np.float64)


def adjust(
    cams: list[CameraRays],
    poses: list[CameraPose],
    free: list[int],
    assoc: Association,
    *,
    prior: HeightPrior,
    tolerance: Tolerance,
    scale_m: float,
    guess: list[CameraPose] | None = None,
    scale_from_heights: bool = False,
) -> Adjusted:
    """Move the ``free`` cameras to fit the rays of ``assoc`` (see the module docstring).

    ``guess``: the starting guesses the weak pull holds each camera towards (default ``poses``): the install's,
    not the last round's, or a direction the people hardly fix (a far camera's distance) would drift round
    after round.

    ``scale_from_heights``: no camera is held, so nothing but the people's heights says how big the site is
    (the residuals are metres at the people: shrinking the whole site would shrink them all). The people's mean
    height is then held at the prior's mean, as firmly as that many people measure it (one residual: each
    person's own height is still left to their rays); with a camera held, its height above the floor sets the
    scale.

    ``scale_m``: the robust loss's scale, as a ray distance (m): rays further than that from their point pull
    less and less. Early, with poses far off, it is wide (every pairing pulls); later, narrow.
    """
    n_cam_params = sum(poses[c].n_params for c in free)
    n_people = assoc.person.shape[0]
    by_cam = np.argsort(assoc.member_camera, kind="stable")  # each camera's memberships one slice
    mc, mi, mp = assoc.member_camera[by_cam], assoc.member_index[by_cam], assoc.member_person[by_cam]
    basis_f, basis_h, inv_sigma = _residual_rows(cams, mc, mi)
    layout = _layout(poses, free, tolerance)
    inv_prior = layout[2]
    f_scale = max(1.0, scale_m * float(np.median(inv_sigma))) if mc.size else 1.0
    # Only the range of people's heights: the prior keeps a person whose rays do not fix a height finite, while a
    # tall person's rays are not pulled off them (the same tall person, seen at every instant, would tilt the
    # cameras).
    height_sigma = (prior.high_m - prior.low_m) / 2.0
    fit = _Projected(
        poses,
        free,
        mc,
        mp,
        n_people,
        (basis_f, basis_h),
        held=guess if guess is not None else poses,
        layout=layout,
        f_scale=f_scale,
        height=(prior.mean_m, height_sigma),
        mean_height=(prior.mean_m, prior.sigma_m) if scale_from_heights else None,
    )
    sol = least_squares(
        fit.residuals,
        np.zeros(n_cam_params),
        jac=fit.jacobian,
        x_scale=PARAM_STEP / inv_prior,
        method="trf",
        ftol=COST_TOLERANCE,
        xtol=STEP_TOLERANCE,
        max_nfev=MAX_EVALUATIONS,
    )
    new = list(poses)
    at = 0
    for ci in free:
        new[ci] = poses[ci].moved(sol.x[at : at + poses[ci].n_params])
        at += poses[ci].n_params
    pts = fit.state(sol.x).person
    mean_h = float(np.median(pts[:, 2])) if n_people else prior.mean_m
    return Adjusted(new, pts, mean_h, float(sol.cost), int(sol.nfev))


def _members(
    cams: list[CameraRays], mc: IntArray, mi: IntArray
) -> tuple[FloatArray, FloatArray, BoolArray, BoolArray, FloatArray]:
    """Per membership (camera ``mc``, blob ``mi``): its foot and head rays (own frame), whether each is seen, and
    its head's plane (zero where the head ray is a point's)."""
    starts = np.cumsum([0] + [c.n for c in cams])
    rows = starts[mc] + mi
    return (
        np.concatenate([c.foot for c in cams])[rows],
        np.concatenate([c.head for c in cams])[rows],
        np.concatenate([c.feet_ok for c in cams])[rows],
        np.concatenate([c.head_ok for c in cams])[rows],
        np.concatenate([np.zeros((c.n, 3)) if c.head_plane is None else c.head_plane for c in cams])[rows],
    )


def _residual_rows(cams: list[CameraRays], mc: IntArray, mi: IntArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Per membership (camera ``mc``, blob ``mi``), the rows B of its residuals in the camera's frame, whitened: a
    person's point v = R (X - C) is off the blob's rays by B v, (m, 2, 3) for the feet and for the head (a box's
    top row: one row, the distance off its plane); and each membership's 1 / point_sigma_m."""
    foot, head, feet_ok, head_ok, plane = _members(cams, mc, mi)
    on_plane = np.any(plane != 0.0, axis=1)
    f1, f2 = _basis(foot)
    h1, h2 = _basis(head)
    h1[on_plane] = plane[on_plane]
    inv_sigma = np.array([1.0 / c.point_sigma_m for c in cams])[mc]
    wf = inv_sigma * feet_ok
    wh = inv_sigma * head_ok
    wh2 = wh * ~on_plane
    basis_f = np.stack([f1 * wf[:, None], f2 * wf[:, None]], axis=1)
    basis_h = np.stack([h1 * wh[:, None], h2 * wh2[:, None]], axis=1)
    return basis_f, basis_h, inv_sigma


def _times(q: FloatArray, r: FloatArray) -> FloatArray:
    """``q[i] @ r`` for every i (one matrix product over the stacked rows: numpy's broadcast is slower)."""
    return np.asarray((q.reshape(-1, 3) @ r).reshape(q.shape), dtype=np.float64)


def _sandwich(r: FloatArray, q: FloatArray) -> FloatArray:
    """``r.T @ q[i] @ r`` for every i."""
    qr = _times(q, r)
    return np.asarray(_times(qr.transpose(0, 2, 1), r).transpose(0, 2, 1), dtype=np.float64)


@dataclass(frozen=True, slots=True, eq=False)
class _State:
    """The people and residuals at one set of camera parameters, and what the Jacobian needs of them."""

    rot: FloatArray
    cen: FloatArray
    person: FloatArray
    res: FloatArray
    """(m, 4) the rays' whitened residuals: feet across, head across."""
    normal: FloatArray
    """(p, 3, 3) each person's last weighted normal equations."""
    weight: FloatArray
    """(m, 4) the robust weights those were built with, per residual row."""
    rows: FloatArray
    """(m, 4, 3) each residual row's derivative by the person's (x, y, h) (feet rows: no h)."""


class _Projected:
    """The adjustment's residuals as functions of the free cameras' parameters alone, each person placed where
    their rays meet (variable projection), and their Jacobian: a residual's derivative by a camera parameter,
    direct, plus through the people it moves (their normal equations, differentiated; the robust weights held)."""

    def __init__(  # noqa: PLR0917 - the one private call site passes what it measured
        self,
        poses: list[CameraPose],
        free: list[int],
        mc: IntArray,
        mp: IntArray,
        n_people: int,
        basis: tuple[FloatArray, FloatArray],
        *,
        held: list[CameraPose],
        layout: tuple[IntArray, IntArray, FloatArray],
        f_scale: float,
        height: tuple[float, float],
        mean_height: tuple[float, float] | None = None,
    ) -> None:
        self.poses, self.free, self.mc, self.mp, self.n_people = poses, free, mc, mp, n_people
        self.basis_f, self.basis_h = basis
        self.held, self.f_scale = held, f_scale
        self.offset, self.width, self.inv_prior = layout
        self.height_mean, self.height_sigma = height
        self.mean_height = mean_height
        """(mean, spread) the people's mean height is held at (one residual, as firm as n people measure it)."""
        m = mc.size
        # Constant per membership: B^T B in the camera's frame (a ray's squared residual is |B R (X - C)|^2).
        self.q_f = np.einsum("mki,mkj->mij", self.basis_f, self.basis_f)
        self.q_h = np.einsum("mki,mkj->mij", self.basis_h, self.basis_h)
        cut = np.flatnonzero(np.diff(mc)) + 1
        self.by_camera = [
            (int(mc[a]), slice(int(a), int(b))) for a, b in zip(np.r_[0, cut], np.r_[cut, m], strict=True) if b > a
        ]
        # Sums over each person's memberships, as one sparse product.
        self.summing = csr_matrix((np.ones(m), (mp, np.arange(m))), shape=(n_people, m))
        self.n_params = int(self.width.sum())
        self._last: tuple[bytes, _State] | None = None

    def state(self, x: FloatArray) -> _State:
        key = np.asarray(x, dtype=np.float64).tobytes()
        if self._last is None or self._last[0] != key:
            self._last = (key, self._solve(x))
        return self._last[1]

    def _solve(self, x: FloatArray) -> _State:
        """Every person-instant where its rays put it, by iteratively reweighted least squares with the robust
        loss's weights; and the rays' whitened residuals there."""
        rot, cen = _rotations(self.poses, self.free, x)
        m, n = self.mc.size, self.n_people
        a_f = np.empty((m, 3, 3))
        a_h = np.empty((m, 3, 3))
        b_f = np.empty((m, 2, 3))
        b_h = np.empty((m, 2, 3))
        c_m = np.empty((m, 3))
        for ci, idx in self.by_camera:
            r = rot[ci]
            a_f[idx] = _sandwich(r, self.q_f[idx])  # the normal equations' matrix of each ray, in the world
            a_h[idx] = _sandwich(r, self.q_h[idx])
            b_f[idx] = _times(self.basis_f[idx], r)  # residual rows in the world: B R
            b_h[idx] = _times(self.basis_h[idx], r)
            c_m[idx] = cen[ci]
        af = a_f[:, :2, :2].reshape(m, 4)  # feet at z = 0: only x, y are unknowns
        rf_c = np.einsum("mij,mj->mi", a_f, c_m)[:, :2]
        ah = a_h.reshape(m, 9)
        rh_c = np.einsum("mij,mj->mi", a_h, c_m)
        weight_f = np.ones((m, 1))
        weight_h = np.ones((m, 1))
        res = np.zeros((m, 4))
        a = np.zeros((n, 3, 3))
        pts = np.zeros((n, 3))
        s = self.summing
        for _ in range(INNER_ROUNDS):
            a = (s @ (weight_h * ah)).reshape(n, 3, 3)
            a[:, :2, :2] += (s @ (weight_f * af)).reshape(n, 2, 2)
            b = s @ (weight_h * rh_c)
            b[:, :2] += s @ (weight_f * rf_c)
            a[:, 2, 2] += 1.0 / self.height_sigma**2 + RIDGE
            a[:, 0, 0] += RIDGE
            a[:, 1, 1] += RIDGE
            b[:, 2] += self.height_mean / self.height_sigma**2
            pts = np.linalg.solve(a, b[..., None])[..., 0]
            used_f, used_h = weight_f, weight_h
            v = pts[self.mp] - c_m
            res[:, 2:4] = (b_h * v[:, None, :]).sum(axis=2)
            v[:, 2] = -c_m[:, 2]  # the feet, on the floor
            res[:, 0:2] = (b_f * v[:, None, :]).sum(axis=2)
            # Cauchy's weight: rho'(z) = 1 / (1 + z), z the squared whitened residual over the scale's square.
            weight_f = 1.0 / (1.0 + (res[:, 0:1] ** 2 + res[:, 1:2] ** 2) / self.f_scale**2)
            weight_h = 1.0 / (1.0 + (res[:, 2:3] ** 2 + res[:, 3:4] ** 2) / self.f_scale**2)
        rows = np.concatenate([b_f, b_h], axis=1)
        rows[:, 0:2, 2] = 0.0
        weight = np.concatenate([np.repeat(used_f, 2, axis=1), np.repeat(used_h, 2, axis=1)], axis=1)
        return _State(rot, cen, pts, res, a, weight, rows)

    def residuals(self, x: FloatArray) -> FloatArray:
        st = self.state(x)
        off = [pose_offset(self.held[ci], st.rot[ci], st.cen[ci]) for ci in self.free]
        out = [_robust(st.res.ravel(), self.f_scale)[0], np.concatenate(off) * self.inv_prior if off else x]
        if self.mean_height is not None:
            mean = self.mean_height[0]
            out.append(np.array([(float(np.mean(st.person[:, 2])) - mean) * self._firm()]))
        return np.concatenate(out)

    def _firm(self) -> float:
        """The mean height's inverse sigma: the people's spread over the square root of their number."""
        return math.sqrt(max(self.n_people, 1)) / self.mean_height[1] if self.mean_height else 0.0

    def jacobian(self, x: FloatArray) -> FloatArray:
        st = self.state(x)
        m, k = self.mc.size, self.n_params
        direct = np.zeros((m, 4, k))
        for ci, idx in self.by_camera:
            at = int(self.offset[ci])
            if at < 0:
                continue
            direct[idx, :, at : at + int(self.width[ci])] = self._camera_rows(st, ci, idx)
        # The people move with the cameras: d person = -N^-1 sum_rays w J_person^T (d residual, direct).
        wp = st.weight[:, :, None] * st.rows  # (m, 4, 3)
        g = (self.summing @ np.einsum("mri,mrk->mik", wp, direct).reshape(m, 3 * k)).reshape(self.n_people, 3, k)
        moved = -np.linalg.solve(st.normal, g)
        jac = direct + np.einsum("mri,mik->mrk", st.rows, moved[self.mp])
        # The pull towards the guesses: its parameters' derivatives, near enough the identity for the steps here.
        rays = jac.reshape(4 * m, k) * _robust(st.res.ravel(), self.f_scale)[1][:, None]
        out = [rays, np.diag(self.inv_prior)]
        if self.mean_height is not None:
            out.append(moved[:, 2, :].mean(axis=0, keepdims=True) * self._firm())
        return np.vstack(out)

    def _camera_rows(self, st: _State, ci: int, idx: slice) -> FloatArray:
        """(n, 4, params) the residual rows' derivatives by camera ``ci``'s own parameters, people held."""
        r, c = st.rot[ci], st.cen[ci]
        pts = st.person[self.mp[idx]]
        feet = pts.copy()
        feet[:, 2] = 0.0
        basis = np.concatenate([self.basis_f[idx], self.basis_h[idx]], axis=1)  # (n, 4, 3), camera frame
        world = np.stack([feet - c, feet - c, pts - c, pts - c], axis=1)  # (n, 4, 3)
        shift = -np.einsum("nrj,ji->nri", basis, r)  # the centre: -B R
        if self.poses[ci].level:
            # R(yaw) = R0 Rz(-yaw): d v / d yaw = -R (z x (X - C)).
            turned = np.cross(np.array([0.0, 0.0, 1.0]), world) @ r.T
            return np.concatenate([-np.einsum("nrj,nrj->nr", basis, turned)[..., None], shift], axis=2)
        # R(w) = exp([w]x) R: d (B v) / d w = rows (v x b).
        v = world @ r.T
        return np.concatenate([np.cross(v, basis), shift], axis=2)


def _robust(res: FloatArray, scale: float) -> tuple[FloatArray, FloatArray]:
    """Cauchy's robust loss put into the residuals themselves (``sign(r) sqrt(rho(r))``, so that a plain least
    squares of them is the robust fit), and the factor each residual's derivative is multiplied by. Only the rays
    go through it: the pull towards the guesses and the scale from heights are priors, meant to hold however
    far the rays pull (scipy's own ``loss`` would apply to them too: a camera far off its guess would cost
    next to nothing)."""
    z = (res / scale) ** 2
    robust = np.sign(res) * scale * np.sqrt(np.log1p(z))
    with np.errstate(divide="ignore", invalid="ignore"):
        factor = np.where(np.abs(res) > SMALL_RESIDUAL, res / (1.0 + z) / robust, 1.0)
    return robust, factor
