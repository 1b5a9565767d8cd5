"""Which rays of one instant are one person, given the cameras' current poses.

A person is a vertical segment: feet at ``(x, y, 0)``, top of the head at ``(x, y, h)``. Every foot ray should pass
through the feet and every head ray through the head; how far a ray passes from its point (the perpendicular
distance, metres at the person) is the residual, weighted by the camera's ``point_sigma_m``.

Per instant, every pair of blobs from two cameras is triangulated into a person (least squares on the four rays,
with a weak prior on the height), but for those whose feet rays pass too far apart to meet at anyone's feet within
the gates; pairs that fit within the gate, in front of both cameras, at a person's height, are taken best first, and
each grows by the blob of every other camera that passes within the gate of its person.
Each blob joins one person at most. A wrong pairing is possible in a crowd: the adjustment's robust loss and the
next association with better poses take care of it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from common.arrays import BoolArray, FloatArray, IntArray
from panostereo.calib.observe import CameraRays
from panostereo.calib.poses import CameraPose

__all__ = [
    "RIDGE",
    "Association",
    "HeightPrior",
    "WorldRays",
    "associate",
    "off_ray",
    "off_rays",
    "triangulate",
    "world_rays",
]


MIN_VIEWS = 2
"""A person needs two cameras' blobs (one camera alone places nobody here)."""
GROWTH_BLOCK = 16
"""Candidate pairs whose people's distances to the instant's blobs are worked out together."""
PARALLEL_SINE = 1e-6
"""Two feet rays whose directions' cross product is shorter than this are taken as parallel (never left out)."""
LINE_SLACK = 1e-9
"""Relative (and metres) slack on the feet rays' distance, so that rounding never leaves out a pair that passes."""
RIDGE = 1e-9
"""Added to a person's normal equations: blobs that fix no point (neither feet nor head in the picture) leave
it finite."""


@dataclass(frozen=True, slots=True)
class HeightPrior:
    """What people's heights are (m): a mean and spread for the fit, and the range a person may have."""

    mean_m: float = 1.7
    sigma_m: float = 0.15
    low_m: float = 1.2
    high_m: float = 2.2


@dataclass(frozen=True, slots=True, eq=False)
class WorldRays:
    """Every blob of every camera as world rays (one row per blob, cameras concatenated)."""

    camera: IntArray
    index: IntArray
    """Row of the blob in its camera's :class:`CameraRays`."""
    instant: IntArray
    centre: FloatArray
    foot: FloatArray
    head: FloatArray
    feet_ok: BoolArray
    head_ok: BoolArray
    weight: FloatArray
    """1 / point_sigma_m^2 of the blob's camera."""
    head_plane: FloatArray
    """World normal of the head's plane (pinhole boxes, :class:`CameraRays`); zero where the head ray is a point's."""

    def take(self, rows: IntArray) -> WorldRays:
        """The blobs ``rows`` alone (one instant's, looked at many times)."""
        return WorldRays(
            self.camera[rows],
            self.index[rows],
            self.instant[rows],
            self.centre[rows],
            self.foot[rows],
            self.head[rows],
            self.feet_ok[rows],
            self.head_ok[rows],
            self.weight[rows],
            self.head_plane[rows],
        )


def world_rays(cams: list[CameraRays], poses: list[CameraPose], use: list[bool] | None = None) -> WorldRays:
    """The blobs of the cameras in ``use`` (default all) as world rays with the given poses."""
    parts = []
    for ci, (c, p) in enumerate(zip(cams, poses, strict=True)):
        if use is not None and not use[ci]:
            continue
        parts.append(
            (
                np.full(c.n, ci, dtype=np.int64),
                np.arange(c.n, dtype=np.int64),
                c.instant,
                np.broadcast_to(p.centre_m, (c.n, 3)),
                c.foot @ p.rotation,
                c.head @ p.rotation,
                c.feet_ok,
                c.head_ok,
                np.full(c.n, 1.0 / c.point_sigma_m**2),
                np.zeros((c.n, 3)) if c.head_plane is None else c.head_plane @ p.rotation,
            )
        )
    if not parts:
        z = np.zeros(0, dtype=np.int64)
        e = np.zeros((0, 3))
        return WorldRays(z, z, z, e, e, e, z.astype(bool), z.astype(bool), np.zeros(0), e)
    cols = list(zip(*parts, strict=True))
    return WorldRays(*(np.concatenate(col) for col in cols))


def _normals(r: WorldRays, rows: IntArray) -> tuple[FloatArray, FloatArray]:
    """Per blob, the normal equations' (3, 3) matrix and (3,) vector of its rays, weighted."""
    f, h, c = r.foot[rows], r.head[rows], r.centre[rows]
    eye = np.eye(3)
    pf = eye - f[:, :, None] * f[:, None, :]
    ph = head_projectors(h, r.head_plane[rows])
    wf = (r.weight[rows] * r.feet_ok[rows])[:, None, None]
    wh = (r.weight[rows] * r.head_ok[rows])[:, None, None]
    m = wh * ph
    m[:, :2, :2] += wf[:, :, 0:1] * pf[:, :2, :2]
    pfc = np.einsum("nij,nj->ni", pf, c)
    phc = np.einsum("nij,nj->ni", ph, c)
    b = wh[:, :, 0] * phc
    b[:, :2] += wf[:, :, 0] * pfc[:, :2]
    return m, b


def head_projectors(head: FloatArray, plane: FloatArray) -> FloatArray:
    """Per blob, the (3, 3) projector whose norm of ``P (X - C)`` is the head point's distance from what the
    blob says of it: across the head ray, or off the head's plane where the blob has one (pinhole boxes)."""
    on_plane = np.any(plane != 0.0, axis=1)[:, None, None]
    across = np.eye(3) - head[:, :, None] * head[:, None, :]
    return np.where(on_plane, plane[:, :, None] * plane[:, None, :], across)


def off_ray(ray: FloatArray, plane: FloatArray, v: FloatArray) -> FloatArray:
    """Per blob, how far a point at ``v`` from the camera is from what the blob says of it (the norm of
    :func:`head_projectors` times ``v``, without building the matrices): across the ray, or off the plane where
    the blob has one (a zero ``plane``: none)."""
    on_plane = np.any(plane != 0.0, axis=-1)
    across = np.linalg.norm(v - np.einsum("...i,...i->...", v, ray)[..., None] * ray, axis=-1)
    return np.where(on_plane, np.abs(np.einsum("...i,...i->...", v, plane)), across)


def _solve(m: FloatArray, b: FloatArray, prior: HeightPrior) -> FloatArray:
    lam = 1.0 / prior.sigma_m**2
    m = m.copy()
    b = b.copy()
    m[..., 2, 2] += lam
    b[..., 2] += lam * prior.mean_m
    m += RIDGE * np.eye(3)
    return np.asarray(np.linalg.solve(m, b[..., None])[..., 0], dtype=np.float64)


def _distances(r: WorldRays, rows: IntArray | None, person: FloatArray) -> tuple[FloatArray, BoolArray]:
    """For blobs ``rows`` (None: every blob of ``r``) against persons (same length, or one for all), the larger of
    the foot and head ray distances (m), and whether the person is in front of the camera."""
    sel = slice(None) if rows is None else rows
    blobs = (r.centre[sel], r.foot[sel], r.head[sel], r.head_plane[sel], r.feet_ok[sel], r.head_ok[sel])
    return off_rays(blobs, np.asarray(person, dtype=np.float64))


def _distances_each(r: WorldRays, person: FloatArray) -> tuple[FloatArray, BoolArray]:
    """:func:`_distances` of every blob of ``r`` from each of the persons (k, 3): (k, n) each."""
    blobs = (r.centre[None], r.foot[None], r.head[None], r.head_plane[None], r.feet_ok[None], r.head_ok[None])
    return off_rays(blobs, np.asarray(person, dtype=np.float64)[:, None, :])


def off_rays(
    blobs: tuple[FloatArray, FloatArray, FloatArray, FloatArray, BoolArray, BoolArray], person: FloatArray
) -> tuple[FloatArray, BoolArray]:
    """The larger of the foot and head ray distances of blobs (centre, foot, head, head plane, feet ok, head ok;
    each (..., 3) or (...,)) from persons (..., 3), broadcast against each other, and whether each person is in
    front of the blob's camera."""
    centre, foot, head, plane, feet_ok, head_ok = blobs
    feet = person.copy()
    feet[..., 2] = 0.0
    vf = feet - centre
    vh = person - centre
    af = np.einsum("...i,...i->...", vf, foot)
    ah = np.einsum("...i,...i->...", vh, head)
    df = np.linalg.norm(vf - af[..., None] * foot, axis=-1)
    dh = off_ray(head, plane, vh)
    d = np.maximum(np.where(feet_ok, df, 0.0), np.where(head_ok, dh, 0.0))
    return d, (af > 0) & (ah > 0)


def _feet_lines_within(r: WorldRays, a: IntArray, b: IntArray, reach: FloatArray) -> BoolArray:
    """Per pair of blobs ``a``, ``b``: whether their feet rays, as lines, may pass within ``reach`` of each other
    (always, where either blob's feet are not in its picture or the rays are near parallel)."""
    ua, ub = r.foot[a], r.foot[b]
    n = np.cross(ua, ub)
    norm = np.linalg.norm(n, axis=1)
    apart = np.abs(np.einsum("ni,ni->n", r.centre[b] - r.centre[a], n))
    crossing = norm > PARALLEL_SINE
    within = ~crossing | (apart <= (reach * (1.0 + LINE_SLACK) + LINE_SLACK) * norm)
    return np.asarray(within | ~(r.feet_ok[a] & r.feet_ok[b]), dtype=bool)


def triangulate(r: WorldRays, members: list[IntArray], prior: HeightPrior) -> FloatArray:
    """The person (x, y, h) of each group of blob rows."""
    m, b = _normals(r, np.arange(r.camera.size, dtype=np.int64))
    out = np.empty((len(members), 3))
    for i, rows in enumerate(members):
        out[i] = _solve(m[rows].sum(axis=0), b[rows].sum(axis=0), prior)
    return out


@dataclass(frozen=True, slots=True, eq=False)
class Association:
    """People found at every instant, and which blobs saw them."""

    person: FloatArray
    """(p, 3) x, y, h of each person-instant."""
    member_person: IntArray
    """(m,) person of each membership."""
    member_camera: IntArray
    member_index: IntArray
    """(m,) row of the blob in its camera's rays."""

    def per_camera(self, n_cameras: int) -> IntArray:
        """How many blobs of each camera were put with a person."""
        return np.bincount(self.member_camera, minlength=n_cameras).astype(np.int64)


def _grown(camera: IntArray, free: BoolArray, pair: tuple[int, int], dist: FloatArray, front: BoolArray) -> list[int]:
    """The blobs of an instant (cameras ``camera``, among ``free``) that join the pair's person: each other camera's
    nearest blob whose rays pass within its camera's gate of the person (``dist``: each blob's distance in its
    camera's gates, ``front``: the person is in front of it), nearest first."""
    js = np.flatnonzero(free & front & (dist <= 1.0))
    taken = {int(camera[pair[0]]), int(camera[pair[1]])}
    out = []
    for j in js[np.argsort(dist[js], kind="stable")].tolist():
        cam = int(camera[j])
        if cam not in taken:
            taken.add(cam)
            out.append(j)
    return out


def _take_best_first(
    here: WorldRays, pairs: tuple[IntArray, IntArray], people: FloatArray, gate: FloatArray
) -> list[tuple[FloatArray, list[int]]]:
    """An instant's people (its blobs ``here``): the candidate ``pairs`` (indices into ``here``, best first, each with
    its person ``people``) taken in turn while both their blobs are free, each grown by the other cameras' blobs
    (:func:`_grown`). Returns each person taken and its blobs (indices into ``here``)."""
    first, second = pairs
    n_here = here.camera.size
    cams_here = here.camera
    gates = gate[cams_here]
    used = np.zeros(n_here, dtype=bool)
    out: list[tuple[FloatArray, list[int]]] = []
    at = 0
    while at < first.size:
        # The next few candidates whose blobs are both still free, each person's distances to every blob of the
        # instant at once (most candidates lose a blob to a better one before their turn: those are skipped before
        # their distances are worked out).
        block = at + np.flatnonzero(~used[first[at:]] & ~used[second[at:]])[:GROWTH_BLOCK]
        if block.size == 0:
            break
        at = int(block[-1]) + 1
        d, front = _distances_each(here, people[block])
        d = d / gates
        for k, c in enumerate(block.tolist()):
            a, b = int(first[c]), int(second[c])
            if used[a] or used[b]:
                continue
            free = ~used
            free[[a, b]] = False
            group = [a, b, *_grown(cams_here, free, (a, b), d[k], front[k])]
            used[group] = True
            out.append((people[c], group))
    return out


def associate(r: WorldRays, gate_m: float | FloatArray, prior: HeightPrior, max_range_m: float) -> Association:
    """Group the blobs of each instant into people (see the module docstring). ``gate_m``: one gate, or one per
    camera (indexed like ``r.camera``): a blob passes when its rays pass within its own camera's gate, and pairs
    are taken best first by their distances in gates."""
    m_all, b_all = _normals(r, np.arange(r.camera.size, dtype=np.int64))
    gate = np.asarray(gate_m, dtype=np.float64)
    if gate.ndim == 0:
        gate = np.full(int(r.camera.max()) + 1 if r.camera.size else 0, float(gate))
    order = np.argsort(r.instant, kind="stable")
    bounds = np.flatnonzero(np.diff(r.instant[order])) + 1
    persons: list[FloatArray] = []
    mem_p: list[int] = []
    mem_rows: list[int] = []
    for rows in np.split(order, bounds):
        if rows.size < MIN_VIEWS or np.unique(r.camera[rows]).size < MIN_VIEWS:
            continue
        ia, ib = np.triu_indices(rows.size, k=1)
        cross = r.camera[rows[ia]] != r.camera[rows[ib]]
        ia, ib = ia[cross], ib[cross]
        # A pair's person within both cameras' gates of both its feet rays lies within the two gates of each ray, so
        # those rays (lines) pass within the sum of the gates of each other: the pairs whose feet rays pass farther
        # apart are left out before they are solved (the others are as they were).
        pa, pb = rows[ia], rows[ib]
        ga, gb = gate[r.camera[pa]], gate[r.camera[pb]]
        near = _feet_lines_within(r, pa, pb, ga + gb)
        ia, ib, pa, pb, ga, gb = ia[near], ib[near], pa[near], pb[near], ga[near], gb[near]
        if ia.size == 0:
            continue
        x = _solve(m_all[pa] + m_all[pb], b_all[pa] + b_all[pb], prior)
        here = r.take(rows)
        da, fa = _distances(here, ia, x)
        db, fb = _distances(here, ib, x)
        cost = np.maximum(da / ga, db / gb)
        reach = np.maximum(np.hypot(*(x[:, :2] - r.centre[pa, :2]).T), np.hypot(*(x[:, :2] - r.centre[pb, :2]).T))
        ok = (cost <= 1.0) & fa & fb & (x[:, 2] >= prior.low_m) & (x[:, 2] <= prior.high_m) & (reach <= max_range_m)
        cand = np.flatnonzero(ok)
        if cand.size == 0:
            continue
        cand = cand[np.argsort(cost[cand], kind="stable")]
        grown: list[tuple[int, IntArray]] = []
        for person, group in _take_best_first(here, (ia[cand], ib[cand]), x[cand], gate):
            pid = len(persons)
            persons.append(person)
            if len(group) > MIN_VIEWS:
                grown.append((pid, rows[np.array(group)]))
            mem_p.extend([pid] * len(group))
            mem_rows.extend(int(rows[j]) for j in group)
        if grown:
            # A person seen by more than the pair is placed by all its blobs (one solve for the instant's groups).
            sums_m = np.array([m_all[g].sum(axis=0) for _, g in grown])
            sums_b = np.array([b_all[g].sum(axis=0) for _, g in grown])
            for (pid, _), person in zip(grown, _solve(sums_m, sums_b, prior), strict=True):
                persons[pid] = person
    rows_arr = np.array(mem_rows, dtype=np.int64)
    return Association(
        person=np.array(persons, dtype=np.float64).reshape(-1, 3),
        member_person=np.array(mem_p, dtype=np.int64),
        member_camera=r.camera[rows_arr] if rows_arr.size else np.zeros(0, dtype=np.int64),
        member_index=r.index[rows_arr] if rows_arr.size else np.zeros(0, dtype=np.int64),
    )
