"""Find a camera that is far from its starting guess, against the cameras already trusted (the anchors).

Association by nearness fails when a camera is turned by more than a few degrees: its rays land metres from the
people they saw, next to other people. The search does not need nearness: one person walking, seen by the camera
and by an anchor over a few instants, already fixes the camera's pose.

1. The anchors place the people they see: each blob whose feet are in the picture is a floor point (its foot
   ray meets the floor), with the head height its head ray gives there.
2. Every pair (a 2D track of the camera, a 2D track of an anchor) seen at the same instants is a guess that
   they follow one person, unless at most of them no pose within twice the install tolerance of the starting
   guess could see the anchor's person along the camera's rays; the camera's pose that fits their rays to the
   anchor's points is a hypothesis (perspective-n-point, OpenCV's SQPnP; for a level camera, a scan of the yaw
   with the position solved linearly at each).
3. Hypotheses outside twice the install tolerance of the starting guess are dropped; the others are scored by
   how many of the camera's blobs, at a spread of instants, pass within the gate of a person the anchors
   place; the best is kept if it explains more than the starting guess does.
"""

from __future__ import annotations

import math
from collections import defaultdict
from dataclasses import dataclass

import cv2
import numpy as np

from common.arrays import FloatArray, IntArray
from panostereo.calib.adjust import Tolerance
from panostereo.calib.associate import HeightPrior, off_rays
from panostereo.calib.observe import CameraRays
from panostereo.calib.poses import CameraPose, pose_change, rotation_z

__all__ = ["AnchorPeople", "Found", "anchor_people", "find_pose", "support"]


MIN_COMMON_INSTANTS = 4
"""A track pair must share this many instants to make a hypothesis (fewer: a person standing, or a glimpse)."""
MIN_TRAVEL_M = 0.5
"""...and the anchor's person must walk at least this far over them (a still person fixes no pose)."""
SCORE_INSTANTS = 80
"""Instants the hypotheses are scored at (spread over the data)."""
YAW_STEP_RAD = math.radians(0.5)
CLEARLY_MORE = 1.2
MIN_GAIN = 10
"""The search's best hypothesis replaces the guess when it explains at least CLEARLY_MORE times as many blobs
as the guess, and MIN_GAIN more (a guess within the association's reach is left to the adjustment)."""
MIN_PNP_POINTS = 4
"""Perspective-n-point needs four correspondences here (feet and heads of two instants)."""
MIN_LEVEL_POINTS = 3
"""A level camera's four parameters need three bearings with elevations."""
IN_FRONT = 1e-3
"""A ray whose forward component is below this is not in front of a pinhole camera."""
SINGULAR = 1e-9
"""A 2x2 determinant below this has no solution."""
"""A level camera's yaw is scanned at this step, then refined."""


@dataclass(frozen=True, slots=True, eq=False)
class AnchorPeople:
    """Floor points of the people the anchors see, one per anchor blob with its feet in the picture."""

    instant: IntArray
    track: IntArray
    """A track id unique over the anchors (camera and the node's 2D track)."""
    point: FloatArray
    """(n, 3) x, y of the feet and the head's height."""


def anchor_people(
    cams: list[CameraRays], poses: list[CameraPose], anchors: list[int], prior: HeightPrior, max_range_m: float
) -> AnchorPeople:
    """The anchors' blobs as people on the floor (see the module docstring)."""
    inst, trk, pts = [], [], []
    for ci in anchors:
        c, p = cams[ci], poses[ci]
        f = c.foot @ p.rotation
        h = c.head @ p.rotation
        with np.errstate(divide="ignore", invalid="ignore"):
            t = -p.centre_m[2] / f[:, 2]
            xy = p.centre_m[:2] + t[:, None] * f[:, :2]
            rho = np.hypot(*(xy - p.centre_m[:2]).T)
            height = p.centre_m[2] + rho * h[:, 2] / np.hypot(h[:, 0], h[:, 1])
        height = np.where(c.head_ok, height, prior.mean_m)
        ok = c.feet_ok & (f[:, 2] < 0) & (rho <= max_range_m) & (height >= prior.low_m) & (height <= prior.high_m)
        inst.append(c.instant[ok])
        trk.append(c.track[ok] * 1000 + ci)
        pts.append(np.column_stack([xy[ok], height[ok]]))
    return AnchorPeople(
        np.concatenate(inst) if inst else np.zeros(0, dtype=np.int64),
        np.concatenate(trk) if trk else np.zeros(0, dtype=np.int64),
        np.concatenate(pts) if pts else np.zeros((0, 3)),
    )


class _Scorer:
    """Counts a camera's blobs that a pose puts within the gate of an anchor person, at a spread of instants."""

    def __init__(self, cam: CameraRays, people: AnchorPeople, gate_m: float) -> None:
        common = np.intersect1d(np.unique(cam.instant), np.unique(people.instant))
        if common.size > SCORE_INSTANTS:
            common = common[np.linspace(0, common.size - 1, SCORE_INSTANTS).round().astype(int)]
        blob, person = _at_one_instant(cam.instant, people.instant)
        scored = np.isin(cam.instant[blob], common)
        self.blob = blob[scored]
        self.person = people.point[person[scored]]
        self.starts = np.flatnonzero(np.r_[True, np.diff(self.blob) != 0]) if self.blob.size else self.blob
        self.gate_m = gate_m
        # Each (blob, person) row's rays in the camera's frame, the same for every pose scored.
        self.rays = (
            cam.foot[self.blob],
            cam.head[self.blob],
            np.zeros((self.blob.size, 3)) if cam.head_plane is None else cam.head_plane[self.blob],
        )
        self.ok = (cam.feet_ok[self.blob], cam.head_ok[self.blob])

    def __call__(self, pose: CameraPose) -> int:
        if self.blob.size == 0:
            return 0
        foot, head, plane = (r @ pose.rotation for r in self.rays)
        d, front = off_rays((pose.centre_m, foot, head, plane, *self.ok), self.person)
        d = np.where(front, d, np.inf)
        best = np.minimum.reduceat(d, self.starts)
        return int(np.count_nonzero(best <= self.gate_m))


def _pnp(rays_cam: FloatArray, points: FloatArray) -> CameraPose | None:
    """The pinhole pose that images ``points`` (n, 3) along ``rays_cam`` (n, 3), by SQPnP."""
    if rays_cam.shape[0] < MIN_PNP_POINTS or np.any(rays_cam[:, 2] <= IN_FRONT):
        return None
    img = rays_cam[:, :2] / rays_cam[:, 2:3]
    try:
        ok, rvec, tvec = cv2.solvePnP(points, img, np.eye(3), None, flags=cv2.SOLVEPNP_SQPNP)
    except cv2.error:  # points too close together to fix a pose (SQPnP refuses them)
        return None
    if not ok:
        return None
    rot = np.asarray(cv2.Rodrigues(rvec)[0], dtype=np.float64)
    return CameraPose(rot, np.asarray(-rot.T @ np.ravel(tvec), dtype=np.float64), level=False)


def _level_fit(rays_cam: FloatArray, points: FloatArray, guess: CameraPose, window_rad: float) -> CameraPose | None:
    """The level pose (yaw, centre) that sees ``points`` along ``rays_cam``: the yaw scanned within the window,
    the centre's x, y by linear least squares at each (each ray's line passes through its point), z from the
    elevations."""
    if rays_cam.shape[0] < MIN_LEVEL_POINTS:
        return None
    b = np.arctan2(rays_cam[:, 1], rays_cam[:, 0])
    yaws = guess.yaw_rad + np.arange(-window_rad, window_rad + YAW_STEP_RAD / 2, YAW_STEP_RAD)
    az = yaws[:, None] + b[None, :]
    s, c = np.sin(az), np.cos(az)
    # (X - Cx) sin(az) - (Y - Cy) cos(az) = 0  ->  Cx sin - Cy cos = X sin - Y cos
    rhs = points[None, :, 0] * s - points[None, :, 1] * c
    a11, a12, a22 = (s * s).sum(1), (-s * c).sum(1), (c * c).sum(1)
    b1, b2 = (s * rhs).sum(1), (-c * rhs).sum(1)
    det = a11 * a22 - a12 * a12
    if np.all(np.abs(det) < SINGULAR):
        return None
    with np.errstate(divide="ignore", invalid="ignore"):
        cx = (a22 * b1 - a12 * b2) / det
        cy = (a11 * b2 - a12 * b1) / det
    res = (cx[:, None] * s - cy[:, None] * c - rhs) ** 2
    k = int(np.nanargmin(res.sum(1)))
    rho = np.hypot(points[:, 0] - cx[k], points[:, 1] - cy[k])
    tan_e = rays_cam[:, 2] / np.hypot(rays_cam[:, 0], rays_cam[:, 1])
    cz = float(np.median(points[:, 2] - rho * tan_e))
    return CameraPose(rotation_z(float(yaws[k])).T, np.array([cx[k], cy[k], cz]), level=True)


@dataclass(frozen=True, slots=True, eq=False)
class Found:
    pose: CameraPose
    score: int
    """Blobs the pose explains at the scored instants."""
    start_score: int
    """...and the starting guess."""
    hypotheses: int


def _by_track(track: IntArray, instant: IntArray) -> dict[int, dict[int, int]]:
    """track -> instant -> row."""
    out: dict[int, dict[int, int]] = defaultdict(dict)
    for i, (t, k) in enumerate(zip(track.tolist(), instant.tolist(), strict=True)):
        out[t][k] = i
    return out


def _at_one_instant(blob_instant: IntArray, person_instant: IntArray) -> tuple[IntArray, IntArray]:
    """Every (camera blob, anchor person) of one instant, as rows into each: blob after blob, each blob's people
    in their order."""
    order = np.argsort(person_instant, kind="stable")
    lo = np.searchsorted(person_instant[order], blob_instant, side="left")
    many = np.searchsorted(person_instant[order], blob_instant, side="right") - lo
    blob = np.repeat(np.arange(blob_instant.size, dtype=np.int64), many)
    kth = np.arange(blob.size) - np.repeat(np.cumsum(many) - many, many)  # the k-th of its blob's people
    return blob, np.asarray(order[np.repeat(lo, many) + kth], dtype=np.int64)


def _track_pairs(
    cam: CameraRays, people: AnchorPeople, guess: CameraPose, window: tuple[float, float], gate_m: float
) -> list[tuple[int, int]]:
    """(camera track, anchor track) pairs seen at ``MIN_COMMON_INSTANTS`` instants or more, at most of which the
    camera's rays could see the anchor's person from a pose within the ``window`` (m, rad) of ``guess``, in the
    order their first common blob comes.

    From such a pose, a ray of the camera seen with the guess's rotation is at most the window's angle off its
    true direction, and the person, seen from the guess's centre rather than the true one, at most
    ``asin(window_m / distance)`` off; the blob's own error adds ``asin(gate_m / distance)``. A pair whose rays miss
    their person by more at most instants cannot be one person seen from within the window: its pose (a fit to
    every instant) is not worked out."""
    i, j = _at_one_instant(cam.instant, people.instant)
    if i.size == 0:
        return []
    window_m, window_rad = window
    fits = np.ones(i.size, dtype=bool)
    feet = people.point[j].copy()
    feet[:, 2] = 0.0
    for pts, rays, ok in ((feet, cam.foot, cam.feet_ok), (people.point[j], cam.head, cam.head_ok)):
        v = pts - guess.centre_m
        dist = np.linalg.norm(v, axis=1)
        world = rays[i] @ guess.rotation
        cos = np.einsum("ni,ni->n", world, v) / np.maximum(dist, SINGULAR)
        with np.errstate(invalid="ignore"):
            reach = (
                window_rad
                + np.arcsin(np.minimum(1.0, window_m / np.maximum(dist, SINGULAR)))
                + np.arcsin(np.minimum(1.0, gate_m / np.maximum(dist, SINGULAR)))
            )
        fits &= ~ok[i] | (np.arccos(np.clip(cos, -1.0, 1.0)) <= reach)
    base = int(people.track.max()) - int(people.track.min()) + 1
    keys = (cam.track[i] - int(cam.track.min())) * base + (people.track[j] - int(people.track.min()))
    _, first, which, count = np.unique(keys, return_index=True, return_inverse=True, return_counts=True)
    fitting = np.bincount(which, weights=fits, minlength=count.size)
    keep = np.flatnonzero((count >= MIN_COMMON_INSTANTS) & (2.0 * fitting >= count))
    rows = first[keep][np.argsort(first[keep], kind="stable")]
    return list(zip(cam.track[i[rows]].tolist(), people.track[j[rows]].tolist(), strict=True))


def support(cam: CameraRays, pose: CameraPose, people: AnchorPeople, gate_m: float) -> int:
    """How many of the camera's blobs (at the scored instants) pass within the gate of an anchor person."""
    return _Scorer(cam, people, gate_m)(pose)


def find_pose(
    cam: CameraRays,
    guess: CameraPose,
    people: AnchorPeople,
    tolerance: Tolerance,
    gate_m: float,
) -> Found:
    """The pose of ``cam`` that best explains the anchors' people, searched within twice the tolerance of
    ``guess`` (see the module docstring)."""
    score = _Scorer(cam, people, gate_m)
    start = score(guess)
    cam_rows = _by_track(cam.track, cam.instant)
    anchor_rows = _by_track(people.track, people.instant)
    best, best_score, tried = guess, -1, 0
    window_m, window_rad = 2.0 * tolerance.centre_m, 2.0 * tolerance.turn_rad
    for t, u in _track_pairs(cam, people, guess, (window_m, window_rad), gate_m):
        common = sorted(set(cam_rows[t]) & set(anchor_rows[u]))
        ci = np.array([cam_rows[t][k] for k in common])
        pj = np.array([anchor_rows[u][k] for k in common])
        pts = people.point[pj]
        if float(np.ptp(pts[:, 0]) ** 2 + np.ptp(pts[:, 1]) ** 2) < MIN_TRAVEL_M**2:
            continue
        feet = pts.copy()
        feet[:, 2] = 0.0
        fo = cam.feet_ok[ci]
        ho = cam.head_ok[ci]
        rays = np.concatenate([cam.foot[ci][fo], cam.head[ci][ho]])
        world = np.concatenate([feet[fo], pts[ho]])
        hyp = _level_fit(rays, world, guess, window_rad) if guess.level else _pnp(rays, world)
        if hyp is None:
            continue
        moved, turned = pose_change(guess, hyp)
        if moved > window_m or turned > window_rad:
            continue
        tried += 1
        s = score(hyp)
        if s > best_score:
            best, best_score = hyp, s
    # A hypothesis is one track pair's pose, rougher than a good guess: it replaces the guess only when it
    # explains clearly more of the camera's blobs.
    if best_score < CLEARLY_MORE * start + MIN_GAIN:
        return Found(guess, start, start, tried)
    return Found(best, best_score, start, tried)
