"""The whole refinement: from every camera's rays and starting guess to refined poses and a report.

1. **Anchors.** The cameras named fixed (surveyed) keep their poses and hold the world frame. With none fixed,
   the camera with the most blobs anchors the search for a while, and every camera is then adjusted with a weak
   pull towards its starting guess, so the site as a whole stays where the guesses put it.
2. **Search** (:mod:`.search`): every other camera is found against the anchors' people, within twice the
   install tolerance of its guess; a camera the anchors share too few people with is searched again against all
   the cameras placed so far.
3. **Association and adjustment**, repeated (:mod:`.associate`, :mod:`.adjust`): with the current poses the
   blobs of each instant are grouped into people within a gate, then the free cameras and the people are
   adjusted to fit; the gate narrows from ``start_gate_m`` to ``final_gate_m`` as the poses improve, and on to
   what each camera's data calls for (a few sigmas of how well its rays meet), so that people closer together
   than a rough gate are told apart and their wrong pairings stop pulling the poses; a camera whose rounds creep
   one way is taken the rest of the way (:func:`_extrapolated`); the rounds stop when no camera moves any more at
   the narrowest gates.
4. A camera that shares fewer than ``min_people`` person-instants with the others cannot be determined: it is
   reported and left as it was (and its blobs are left out, so a wrong pose does not pull the others).

Ground truth is never read here: the rays and the starting guesses are all there is.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from functools import partial

import numpy as np
from threadpoolctl import threadpool_limits

from common.arrays import FloatArray
from panostereo.calib.adjust import Tolerance, adjust, ray_distances
from panostereo.calib.associate import Association, HeightPrior, WorldRays, associate, triangulate, world_rays
from panostereo.calib.observe import CameraRays
from panostereo.calib.poses import CameraPose, pose_change, pose_offset, rotation_z
from panostereo.calib.search import anchor_people, find_pose

__all__ = ["CameraReport", "RefineSettings", "Refined", "refine"]

logger = logging.getLogger(__name__)

SCHEDULED_ROUNDS = 3
"""The gate narrows from ``start_gate_m`` to ``final_gate_m`` over this many rounds, and on at that pace to what
the data calls for."""


@dataclass(frozen=True, slots=True)
class RefineSettings:
    """The refinement's knobs; every one physical."""

    tolerance: Tolerance = field(default_factory=Tolerance)
    """How far a starting guess may be off (m, rad): the search looks within twice that."""
    height: HeightPrior = field(default_factory=HeightPrior)
    max_range_m: float = 100.0
    """People further than this from a camera are not used (too few pixels to place them)."""
    search_gate_m: float = 0.5
    """The search counts a blob as explained when its rays pass this close to an anchor's person."""
    start_gate_m: float = 0.6
    """The first association's gate (m at the person): what the search leaves of a camera's error."""
    final_gate_m: float = 0.3
    """A few sigmas of where a rough box's rays put a person; the gate at which the data's spread is measured."""
    gate_per_residual: float = 3.0
    """Below ``final_gate_m`` the gate narrows on to what the data calls for: this many times the median distance
    of the rays from their people (about 3.5 sigmas), so that two people closer than ``final_gate_m`` are no
    longer taken for one and their wrong pairings stop pulling the poses."""
    min_gate_m: float = 0.02
    """...but not below this (people sway; boxes are whole pixels)."""
    min_people: int = 30
    """A camera sharing fewer person-instants with the others is left as it was (undetermined)."""
    max_people: int = 5000
    """The adjustment uses at most this many person-instants, spread over the data: more cost time and move a
    camera by less than the people's own noise. Once the first round has found more, the later rounds associate
    only every k-th instant, enough for this many (the people of the others would not be used)."""
    max_rounds: int = 10
    settled_m: float = 0.005
    settled_rad: float = math.radians(0.02)
    """Rounds stop once no camera moves more than this between two."""


@dataclass(frozen=True, slots=True)
class CameraReport:
    """What happened to one camera."""

    sensor_id: str
    status: str
    """``fixed``, ``refined`` or ``undetermined``."""
    moved_m: float
    turned_deg: float
    residual_before_m: float
    """Median distance of its rays from the people they were put with, with the starting poses (m at the
    person; NaN: none)."""
    residual_after_m: float
    residual_before_px: float
    """The same as pixels (pinhole cameras: angle x focal length; NaN otherwise)."""
    residual_after_px: float
    people: int
    """Person-instants it saw together with other cameras."""
    blobs: int
    note: str = ""

    def to_dict(self) -> dict[str, object]:
        def num(x: float, digits: int) -> float | None:
            return None if not math.isfinite(x) else round(x, digits)

        return {
            "sensor_id": self.sensor_id,
            "status": self.status,
            "moved_m": num(self.moved_m, 3),
            "turned_deg": num(self.turned_deg, 3),
            "residual_before_m": num(self.residual_before_m, 3),
            "residual_after_m": num(self.residual_after_m, 3),
            "residual_before_px": num(self.residual_before_px, 1),
            "residual_after_px": num(self.residual_after_px, 1),
            "people": self.people,
            "blobs": self.blobs,
            "note": self.note,
        }


@dataclass(frozen=True, slots=True, eq=False)
class Refined:
    poses: list[CameraPose]
    cameras: list[CameraReport]
    rounds: int


def _search(
    cams: list[CameraRays], poses: list[CameraPose], anchors: list[int], todo: list[int], s: RefineSettings
) -> dict[int, int]:
    """Search each camera of ``todo`` against ``anchors``; updates ``poses``; returns each one's support."""
    people = anchor_people(cams, poses, anchors, s.height, s.max_range_m)
    out = {}
    for ci in todo:
        found = find_pose(cams[ci], poses[ci], people, s.tolerance, s.search_gate_m)
        logger.info(
            "%s: search from %d to %d blobs explained (%d hypotheses)",
            cams[ci].sensor_id,
            found.start_score,
            found.score,
            found.hypotheses,
        )
        poses[ci] = found.pose
        out[ci] = found.score
    return out


def _medians(
    cams: list[CameraRays], poses: list[CameraPose], assoc: Association, person: np.ndarray
) -> list[tuple[float, float]]:
    """Per camera, the median ray distance (m) and the median ray angle (rad) of its memberships."""
    foot, head = ray_distances(cams, poses, assoc, person)
    dist = np.concatenate([foot, head])
    cam = np.concatenate([assoc.member_camera, assoc.member_camera])
    pts = np.concatenate([person[assoc.member_person] * [1, 1, 0], person[assoc.member_person]])
    cen = np.stack([p.centre_m for p in poses])[cam] if cam.size else np.zeros((0, 3))
    rng = np.linalg.norm(pts - cen, axis=1) if cam.size else np.zeros(0)
    out = []
    for ci in range(len(cams)):
        sel = (cam == ci) & np.isfinite(dist)
        if not np.any(sel):
            out.append((math.nan, math.nan))
            continue
        out.append((float(np.median(dist[sel])), float(np.median(dist[sel] / np.maximum(rng[sel], 1e-6)))))
    return out


def _focal_px(cam: CameraRays) -> float:
    from common.schema import PinholeModel

    if cam.pose.level or not isinstance(cam.info.model, PinholeModel):
        return math.nan
    return float(cam.info.model.k[0])


BLAS_THREADS = 1
"""The refinement's linear algebra runs on one BLAS thread: its matrices are tall and thin (a row per ray, a column per
camera parameter), where OpenBLAS's threads take about a third more CPU time and finish no sooner."""


def refine(cams: list[CameraRays], fixed: Sequence[str], settings: RefineSettings | None = None) -> Refined:
    """Refine every camera not in ``fixed`` (see the module docstring)."""
    with threadpool_limits(limits=BLAS_THREADS, user_api="blas"):
        return _refine(cams, fixed, settings or RefineSettings())


def _refine(cams: list[CameraRays], fixed: Sequence[str], s: RefineSettings) -> Refined:
    start = [c.pose for c in cams]
    poses = list(start)
    fixed_idx = [i for i, c in enumerate(cams) if c.sensor_id in set(fixed)]
    n = len(cams)
    if n == 0:
        return Refined([], [], 0)
    anchors = fixed_idx or [int(np.argmax([c.n for c in cams]))]
    others = [i for i in range(n) if i not in anchors]
    support = _search(cams, poses, anchors, others, s)
    weak = [i for i in others if support[i] < s.min_people]
    placed = anchors + [i for i in others if i not in weak]
    if weak and len(placed) > len(anchors):
        support.update(_search(cams, poses, placed, weak, s))
    # With none fixed every camera is adjusted, the people's mean height keeping the site from shrinking (the
    # residuals are metres at the people); the whole is then put where the guesses are (:func:`_as_a_whole`).
    free = [i for i in range(n) if i not in fixed_idx]
    use = [True] * n
    rounds = 0
    assoc = None
    counts = np.zeros(n, dtype=np.int64)
    height = s.height
    narrowing = _Narrowing(s)
    settled = False
    steps: dict[int, FloatArray] = {}
    stride = 1
    for rounds in range(1, s.max_rounds + 1):
        gate = narrowing.gate(rounds, settled, partial(_data_gate, cams, poses, use, height, s, stride))
        assoc, counts = _associate_round(cams, poses, (start, free, use), gate, height, s, stride)
        moving = [i for i in free if use[i]]
        if not moving or assoc.member_camera.size == 0:
            break
        sub = _spread_people(assoc, s.max_people)
        res = adjust(
            cams,
            poses,
            moving,
            sub,
            prior=height,
            tolerance=s.tolerance,
            scale_m=float(np.median(gate)) / 2.0,
            guess=start,
            scale_from_heights=not fixed_idx,
        )
        change = [pose_change(poses[i], res.poses[i]) for i in moving]
        settled = all(d <= s.settled_m and a <= s.settled_rad for d, a in change)
        steps, poses, further = _extrapolated(poses, res.poses, moving, steps, s.tolerance, settled=settled)
        if fixed_idx:  # else the prior's mean holds the scale, and stays the prior's
            height = replace(height, mean_m=res.mean_height_m)
        logger.info(
            "round %d: gate %s m, %d people (mean height %.2f m) of %s, %d rays, largest change %.3f m %.3f deg%s",
            rounds,
            _gates(gate),
            assoc.person.shape[0],
            height.mean_m,
            "every instant" if stride == 1 else f"1 instant in {stride}",
            assoc.member_camera.size,
            max(c[0] for c in change),
            math.degrees(max(c[1] for c in change)),
            f", taken further: {', '.join(cams[i].sensor_id for i in further)}" if further else "",
        )
        if settled and narrowing.narrowest:
            break
        if stride == 1 and assoc.person.shape[0] > s.max_people:
            stride = assoc.person.shape[0] // s.max_people
    if not fixed_idx:
        poses = _as_a_whole(start, poses, [i for i in range(n) if use[i]])
    if stride > 1 and assoc is not None:  # the report counts every instant's people
        assoc = associate(_rays(cams, poses, use, 1), gate, height, s.max_range_m)
        counts = _person_counts(assoc, n)
    reports = _report(cams, start, poses, fixed_idx, use, assoc, counts, s)
    return Refined(poses, reports, rounds)


def _associate_round(  # noqa: PLR0917 - the round's state, one private call site
    cams: list[CameraRays],
    poses: list[CameraPose],
    cameras: tuple[list[CameraPose], list[int], list[bool]],
    gate: float | FloatArray,
    height: HeightPrior,
    s: RefineSettings,
    stride: int,
) -> tuple[Association, np.ndarray]:
    """A round's association of every ``stride``-th instant, and each camera's person-instants (estimated for every
    instant). ``cameras``: the starting guesses, the free cameras and those in use; a free camera with fewer than
    ``min_people`` is put back at its guess and left out from now on (``poses`` and ``use`` are updated)."""
    start, free, use = cameras
    assoc = associate(_rays(cams, poses, use, stride), gate, height, s.max_range_m)
    counts = _person_counts(assoc, len(cams)) * stride
    dropped = [i for i in free if use[i] and counts[i] < s.min_people]
    for i in dropped:
        use[i] = False
        poses[i] = start[i]
    if dropped:
        logger.info("undetermined: %s", ", ".join(cams[i].sensor_id for i in dropped))
        assoc = associate(_rays(cams, poses, use, stride), gate, height, s.max_range_m)
    return assoc, counts


ALIGNED_RAD = math.radians(10.0)
"""Two successive steps of a camera within this angle of each other go one way: the rounds creep (Besl and
McKay's accelerated ICP, IEEE PAMI 14(2), 1992)."""
MAX_EXTRAPOLATION = 10.0
"""An extrapolation goes at most this many of the last step further."""


def _extrapolated(
    before: list[CameraPose],
    after: list[CameraPose],
    moving: list[int],
    last: dict[int, FloatArray],
    tol: Tolerance,
    *,
    settled: bool = False,
) -> tuple[dict[int, FloatArray], list[CameraPose], list[int]]:
    """Each moving camera's step this round, the poses after it, taken further where the rounds creep, and the
    cameras taken further (none once every camera has ``settled``: the rounds may stop here, and no pose is left
    where no adjustment has checked it).

    Each round associates with the poses it starts from, so a camera far off its pose keeps people whose rays meet
    its wrong pose, and the adjustment moves it part of the way only: round after round it steps the same way,
    by steps that shrink by a ratio r. Where two successive steps are aligned (``ALIGNED_RAD``, in units of the
    install tolerance) and shrink, the rest of the way is the geometric series' remainder, r / (1 - r) of the
    last step (Aitken's extrapolation; at most ``MAX_EXTRAPOLATION`` of it, and no farther than the install
    tolerance): the next association then starts there, and its adjustment takes back whatever went too far."""
    out = list(after)
    steps: dict[int, FloatArray] = {}
    further: list[int] = []
    for i in moving:
        step = pose_offset(before[i], after[i].rotation, after[i].centre_m)
        steps[i] = step
        prev = last.get(i)
        if settled or prev is None or prev.shape != step.shape:
            continue
        turns = 1 if before[i].level else 3
        unit = np.concatenate([np.full(turns, tol.turn_rad), np.full(3, tol.centre_m)])
        a, b = prev / unit, step / unit
        na, nb = float(np.linalg.norm(a)), float(np.linalg.norm(b))
        if na <= 0.0 or nb <= 0.0 or nb >= na:
            continue
        if math.acos(max(-1.0, min(1.0, float(a @ b) / (na * nb)))) > ALIGNED_RAD:
            continue
        ratio = nb / na
        # No further than the install tolerance: the guess was within it of the truth.
        out[i] = after[i].moved(min(ratio / (1.0 - ratio), MAX_EXTRAPOLATION, 1.0 / nb) * step)
        further.append(i)
    return steps, out, further


def _as_a_whole(start: list[CameraPose], poses: list[CameraPose], placed: list[int]) -> list[CameraPose]:
    """The ``placed`` cameras' poses as one body, scaled about the floor, turned about the vertical and shifted on
    it so that their centres are as near their starting guesses as they can be (least squares: the guesses as a
    whole say where the site is, which way it faces and how big it is when no camera is surveyed). Every ray keeps
    its direction, so the fit to the people is the same; the others are left as they are."""
    if len(placed) < 2:  # noqa: PLR2004 - one camera: its own guess, nothing to fit
        return poses
    p = np.array([poses[i].centre_m for i in placed])
    q = np.array([start[i].centre_m for i in placed])
    pc, qc = p[:, :2].mean(axis=0), q[:, :2].mean(axis=0)
    dp, dq = p[:, :2] - pc, q[:, :2] - qc
    h = dp.T @ dq
    turn = rotation_z(math.atan2(h[0, 1] - h[1, 0], h[0, 0] + h[1, 1]))
    turned = dp @ turn[:2, :2].T
    size = float((np.sum(turned * dq) + p[:, 2] @ q[:, 2]) / (np.sum(dp * dp) + p[:, 2] @ p[:, 2]))
    out = list(poses)
    for i in placed:
        c = poses[i].centre_m
        xy = size * (turn[:2, :2] @ (c[:2] - pc)) + qc
        out[i] = CameraPose(poses[i].rotation @ turn.T, np.array([*xy, size * c[2]]), poses[i].level)
    return out


class _Narrowing:
    """The association's gate round by round: from ``start_gate_m`` to ``final_gate_m`` over ``SCHEDULED_ROUNDS``
    rounds, then on at that pace down to what the data calls for (:func:`_data_gate`), and straight there once the
    poses settle (the gradual narrowing is for cameras that still move)."""

    def __init__(self, s: RefineSettings) -> None:
        self.s = s
        self.pace = (s.final_gate_m / s.start_gate_m) ** (1.0 / SCHEDULED_ROUNDS)
        self.floor: FloatArray | None = None
        self.narrowest = False
        """The gate has reached what the data calls for."""

    def gate(self, rounds: int, settled: bool, measure: Callable[[], FloatArray]) -> float | FloatArray:
        """The gate of round ``rounds``: one for every camera while it narrows to ``final_gate_m``, then each
        camera's own (:func:`_data_gate`) where the narrowing has gone below it."""
        s = self.s
        gate = s.start_gate_m * self.pace ** (rounds - 1)
        self.narrowest = self.narrowest or settled
        if gate >= s.final_gate_m and not self.narrowest:
            return gate
        # Measured when the narrowing first goes below the rough gate, and again once it gets to the widest
        # camera's (the poses have improved since).
        if self.floor is None or self.narrowest or gate <= float(self.floor.max()):
            self.floor = measure()
        self.narrowest = self.narrowest or gate <= float(self.floor.max())
        return self.floor if self.narrowest else np.maximum(self.floor, gate)


def _gates(gate: float | FloatArray) -> str:
    """The round's gate as the log says it: one, or the narrowest to the widest camera's."""
    g = np.atleast_1d(np.asarray(gate, dtype=np.float64))
    lo, hi = f"{float(g.min()):.2f}", f"{float(g.max()):.2f}"
    return lo if lo == hi else f"{lo}-{hi}"


def _rays(cams: list[CameraRays], poses: list[CameraPose], use: list[bool], stride: int) -> WorldRays:
    """The blobs of the cameras in ``use`` as world rays, of every ``stride``-th instant only."""
    r = world_rays(cams, poses, use)
    if stride <= 1:
        return r
    kept = np.unique(r.instant)[::stride]
    return r.take(np.flatnonzero(np.isin(r.instant, kept)))


def _data_gate(  # noqa: PLR0917 - bound with partial at its one call site
    cams: list[CameraRays],
    poses: list[CameraPose],
    use: list[bool],
    height: HeightPrior,
    s: RefineSettings,
    stride: int,
) -> FloatArray:
    """The gate each camera's data calls for with the current poses: ``gate_per_residual`` times the median
    distance of its blobs (the farther of their two rays) from the people they are put with at ``final_gate_m``
    (measured there every time, so that the gate does not shrink on its own narrower choices), between
    ``min_gate_m`` and ``final_gate_m``; of every ``stride``-th instant's people. Per camera: a far camera's rays
    pass farther from their people than a near one's, and a camera still off its pose has its rays' distances, not
    the others'."""
    wide = associate(_rays(cams, poses, use, stride), s.final_gate_m, height, s.max_range_m)
    dist = np.fmax(*ray_distances(cams, poses, wide, wide.person))  # a blob's distance, as the association's
    out = np.full(len(cams), s.final_gate_m)
    for c in range(len(cams)):
        mine = dist[(wide.member_camera == c) & np.isfinite(dist)]
        if mine.size:
            out[c] = min(s.final_gate_m, max(s.min_gate_m, s.gate_per_residual * float(np.median(mine))))
    return out


def _spread_people(assoc: Association, most: int) -> Association:
    """At most ``most`` of the people of ``assoc``, evenly spread over them (they are in instant order)."""
    n = assoc.person.shape[0]
    if n <= most:
        return assoc
    keep = np.unique(np.linspace(0, n - 1, most).round().astype(np.int64))
    new_id = np.full(n, -1, dtype=np.int64)
    new_id[keep] = np.arange(keep.size)
    sel = new_id[assoc.member_person] >= 0
    return Association(
        person=assoc.person[keep],
        member_person=new_id[assoc.member_person[sel]],
        member_camera=assoc.member_camera[sel],
        member_index=assoc.member_index[sel],
    )


def _person_counts(assoc: Association, n: int) -> np.ndarray:
    """Person-instants each camera saw with another camera."""
    return assoc.per_camera(n)


def _report(  # noqa: PLR0917 - one private call site, every value it reports
    cams: list[CameraRays],
    start: list[CameraPose],
    poses: list[CameraPose],
    fixed_idx: list[int],
    use: list[bool],
    assoc: Association | None,
    counts: np.ndarray,
    s: RefineSettings,
) -> list[CameraReport]:
    n = len(cams)
    if assoc is not None and assoc.member_camera.size:
        before_people = _triangulate_with(cams, start, assoc, s.height)
        before = _medians(cams, start, assoc, before_people)
        after = _medians(cams, poses, assoc, _triangulate_with(cams, poses, assoc, s.height))
    else:
        before = after = [(math.nan, math.nan)] * n
    out = []
    for i, c in enumerate(cams):
        moved, turned = pose_change(start[i], poses[i])
        f = _focal_px(c)
        if i in fixed_idx:
            status, note = "fixed", "held as surveyed (--fix)"
        elif not use[i]:
            status = "undetermined"
            note = (
                f"too few people seen with other cameras ({int(counts[i])} person-instants, need "
                f"{s.min_people}): left as it was"
            )
        else:
            status, note = "refined", ""
        out.append(
            CameraReport(
                sensor_id=c.sensor_id,
                status=status,
                moved_m=moved,
                turned_deg=math.degrees(turned),
                residual_before_m=before[i][0],
                residual_after_m=after[i][0],
                residual_before_px=before[i][1] * f,
                residual_after_px=after[i][1] * f,
                people=int(counts[i]),
                blobs=c.n,
                note=note,
            )
        )
    return out


def _triangulate_with(
    cams: list[CameraRays], poses: list[CameraPose], assoc: Association, height: HeightPrior
) -> np.ndarray:
    """The people of ``assoc`` triangulated from their rays with ``poses``."""
    r = world_rays(cams, poses)
    starts = np.cumsum([0] + [c.n for c in cams])
    rows = starts[assoc.member_camera] + assoc.member_index
    order = np.argsort(assoc.member_person, kind="stable")
    bounds = np.flatnonzero(np.diff(assoc.member_person[order])) + 1
    members = [rows[g] for g in np.split(order, bounds)]
    return triangulate(r, members, height)
