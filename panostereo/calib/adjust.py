"""Bundle adjustment: the poses of the free cameras and every person-instant, from the rays put together.

Unknowns: each free camera's pose parameters (:mod:`.poses`: six for a pinhole camera, four for a level one) and
each person-instant's ``(x, y, h)``. Residuals, each divided by its sigma so a residual of 1 is one sigma:

* every foot ray's and head ray's perpendicular distance from its point, as two components across the ray
  (metres at the person, sigma the camera's ``point_sigma_m``);
* each person's height against the people's mean height (a parameter too: the prior's spread keeps each height
  near the others', while the scale of the site is left to the rays);
* each free camera's parameters against its starting guess, with the install tolerance as sigma: a weak pull that
  only fixes what the people cannot (where the site is on the floor and which way it faces, when no camera is
  held fixed).

scipy's ``least_squares`` solves it with a robust loss (a wrong pairing costs little) and the Jacobian's
sparsity (a ray depends on one camera and one person), so its finite differences need only a few evaluations.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares
from scipy.sparse import coo_matrix, csr_matrix

from common.arrays import FloatArray, IntArray
from common.pinhole import rotation_from_rvec
from panostereo.calib.associate import Association, HeightPrior, head_projectors
from panostereo.calib.observe import CameraRays
from panostereo.calib.poses import CameraPose, rotation_z

__all__ = ["Adjusted", "Tolerance", "adjust", "ray_distances"]

NOT_VERTICAL = 0.9
"""A ray whose z component is below this is crossed with the vertical to build its basis, else with x."""
ROBUST_LOSS = "cauchy"
"""scipy's robust loss: a residual far past one sigma (a wrong pairing, a clutter box) hardly pulls."""
MAX_EVALUATIONS = 60
"""Steps per adjustment (each association is followed by one)."""
COST_TOLERANCE = 1e-3
"""An adjustment stops when a step lowers the cost by less than this fraction: the next association moves the
cameras further than the last fraction of a step would."""
LSMR_TOLERANCE = 1e-10
"""The inner linear solver's tolerance: loose ones leave the cameras' position-versus-turn trade-off unsolved."""


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
    """The people's mean height: estimated, so the height prior pulls each towards the others, not the scale."""
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
    mc, mi = assoc.member_camera, assoc.member_index
    foot = np.concatenate([cams[c].foot[i][None] for c, i in zip(mc, mi, strict=True)]) if mc.size else np.zeros((0, 3))
    head = np.concatenate([cams[c].head[i][None] for c, i in zip(mc, mi, strict=True)]) if mc.size else np.zeros((0, 3))
    ok_f = np.array([cams[c].feet_ok[i] for c, i in zip(mc, mi, strict=True)], dtype=bool)
    ok_h = np.array([cams[c].head_ok[i] for c, i in zip(mc, mi, strict=True)], dtype=bool)
    plane = np.array(
        [[0.0, 0.0, 0.0] if cams[c].head_plane is None else cams[c].head_plane[i] for c, i in zip(mc, mi, strict=True)]
    ).reshape(-1, 3)
    p = person[assoc.member_person]
    feet = p.copy()
    feet[:, 2] = 0.0
    out = []
    for pt, d, ok in ((feet, foot, ok_f), (p, head, ok_h)):
        v = np.einsum("mij,mj->mi", rot[mc], pt - cen[mc])
        proj = head_projectors(d, plane if d is head else np.zeros_like(d))
        out.append(np.where(ok, np.linalg.norm(np.einsum("mij,mj->mi", proj, v), axis=1), np.nan))
    return out[0], out[1]


def _sparsity(
    mc: IntArray, mp: IntArray, *, cam_offset: IntArray, cam_width: IntArray, n_people: int, n_cam_params: int
) -> csr_matrix:
    """Which residuals depend on which unknowns: a ray's rows on its person's 3 columns and on its camera's
    parameters when that is free; a height on its person's h and the mean height; a prior on its parameter."""
    m = mc.size
    ray_rows = np.arange(4 * m).reshape(m, 4)
    r_idx: list[IntArray] = [np.tile(ray_rows.ravel(), 3)]
    c_idx: list[IntArray] = [np.concatenate([np.repeat(n_cam_params + 3 * mp + k, 4) for k in range(3)])]
    free_m = cam_offset[mc] >= 0
    for k in range(int(cam_width.max(initial=0))):
        sel = free_m & (k < cam_width[mc])
        r_idx.append(ray_rows[sel].ravel())
        c_idx.append(np.repeat(cam_offset[mc][sel] + k, 4))
    r_idx += [4 * m + np.arange(n_people)] * 2
    c_idx += [n_cam_params + 3 * np.arange(n_people) + 2, np.full(n_people, n_cam_params + 3 * n_people)]
    r_idx.append(4 * m + n_people + np.arange(n_cam_params))
    c_idx.append(np.arange(n_cam_params))
    rr = np.concatenate(r_idx)
    cc = np.concatenate(c_idx)
    n_res = 4 * m + n_people + n_cam_params
    sparsity: csr_matrix = coo_matrix(
        (np.ones(rr.size), (rr, cc)), shape=(n_res, n_cam_params + 3 * n_people + 1)
    ).tocsr()
    sparsity.data[:] = 1.0
    return sparsity


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
) -> Adjusted:
    """Move the ``free`` cameras to fit the rays of ``assoc`` (see the module docstring).

    ``scale_m``: the robust loss's scale, as a ray distance (m): rays further than that from their point pull
    less and less. Early, with poses far off, it is wide (every pairing pulls); later, narrow.
    """
    n_cam_params = sum(poses[c].n_params for c in free)
    n_people = assoc.person.shape[0]
    mc, mi, mp = assoc.member_camera, assoc.member_index, assoc.member_person
    m = mc.size
    starts = np.cumsum([0] + [c.n for c in cams])
    rows = starts[mc] + mi
    foot = np.concatenate([c.foot for c in cams])[rows]
    head = np.concatenate([c.head for c in cams])[rows]
    feet_ok = np.concatenate([c.feet_ok for c in cams])[rows]
    head_ok = np.concatenate([c.head_ok for c in cams])[rows]
    plane = np.concatenate([np.zeros((c.n, 3)) if c.head_plane is None else c.head_plane for c in cams])[rows]
    on_plane = np.any(plane != 0.0, axis=1)
    f1, f2 = _basis(foot)
    h1, h2 = _basis(head)
    h1[on_plane] = plane[on_plane]  # a box's top row: only the distance off its plane counts
    inv_sigma = np.array([1.0 / c.point_sigma_m for c in cams])[mc]
    wf = inv_sigma * feet_ok
    wh = inv_sigma * head_ok
    wh2 = wh * ~on_plane
    cam_offset, cam_width, inv_prior = _layout(poses, free, tolerance)

    def residuals(x: FloatArray) -> FloatArray:
        rot, cen = _rotations(poses, free, x)
        pts = x[n_cam_params:-1].reshape(n_people, 3)
        pp = pts[mp]
        r_m, c_m = rot[mc], cen[mc]
        feet = pp.copy()
        feet[:, 2] = 0.0
        vf = np.einsum("mij,mj->mi", r_m, feet - c_m)
        vh = np.einsum("mij,mj->mi", r_m, pp - c_m)
        res = np.empty(4 * m + n_people + n_cam_params)
        res[0 : 4 * m : 4] = np.einsum("mi,mi->m", vf, f1) * wf
        res[1 : 4 * m : 4] = np.einsum("mi,mi->m", vf, f2) * wf
        res[2 : 4 * m : 4] = np.einsum("mi,mi->m", vh, h1) * wh
        res[3 : 4 * m : 4] = np.einsum("mi,mi->m", vh, h2) * wh2
        res[4 * m : 4 * m + n_people] = (pts[:, 2] - x[-1]) / prior.sigma_m
        res[4 * m + n_people :] = x[:n_cam_params] * inv_prior
        return res

    sparsity = _sparsity(
        mc, mp, cam_offset=cam_offset, cam_width=cam_width, n_people=n_people, n_cam_params=n_cam_params
    )
    sol = least_squares(
        residuals,
        np.concatenate([np.zeros(n_cam_params), assoc.person.ravel(), [prior.mean_m]]),
        jac_sparsity=sparsity,
        loss=ROBUST_LOSS,
        f_scale=max(1.0, scale_m * float(np.median(inv_sigma))) if m else 1.0,
        x_scale="jac",
        method="trf",
        tr_solver="lsmr",
        tr_options={"atol": LSMR_TOLERANCE, "btol": LSMR_TOLERANCE},
        ftol=COST_TOLERANCE,
        max_nfev=MAX_EVALUATIONS,
    )
    new = list(poses)
    at = 0
    for ci in free:
        new[ci] = poses[ci].moved(sol.x[at : at + poses[ci].n_params])
        at += poses[ci].n_params
    return Adjusted(new, sol.x[n_cam_params:-1].reshape(n_people, 3), float(sol.x[-1]), float(sol.cost), int(sol.nfev))
