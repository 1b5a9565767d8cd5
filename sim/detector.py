"""A simulated person detector on corner cameras: a multi-view detection dataset with what real detectors do.

Real multi-camera rooms (a few perspective cameras high in the corners, a dozen people who come and go by a
door and hide each other) are what the tracker is measured on, and no such set with ground truth ships with
the project. This writes one, in the ``mot`` layout that ``panostereo import mot`` reads: ``calib/<cam>.json``
(pinhole), ``detections/<cam>.txt`` (MOTChallenge rows) and ``gt.csv`` (the people's floor positions; each stay
in the room is one identity, ``person.visit``: a person who leaves by the door and comes back is, to anyone
without their face, someone who came in).

People walk as in the simulated world (:mod:`sim.walkers`: smooth paths, pauses, avoiding each other, entering
and leaving by the door on the wall y = 0). Each camera's detector sees each person as a box, feet to head
top, one shoulder width wide, and behaves as a real one does:

* **occlusion**: the share of a person's box covered by the boxes of people nearer to the camera sets what the
  detector can see; a person mostly hidden is missed, a partly hidden one is found with a lower score and a box
  cut where the nearer person begins (its bottom is then not the feet);
* **misses and scores**: a visible person is found with probability ``p_detect``, its score drawn high; partly
  hidden ones with a falling probability and score;
* **noise**: every box edge moves by ``box_noise`` of the box height (1 sigma);
* **clutter**: false boxes (``clutter_per_frame`` per camera and frame, Poisson), person-sized at random floor
  points of the room, with low scores; and now and then a second box on one person (``double_prob``).

Everything is drawn from ``seed``: the same arguments write the same files.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from common.arrays import FloatArray
from common.errors import ConfigError
from common.site import WorldSpec
from sim.people import Door
from sim.walkers import WalkerSim

__all__ = ["DetectorModel", "RoomCameras", "write_room_dataset"]

PERSON_HALF_WIDTH_M = 0.22
"""Half a person's width seen from any side (the box's half width on the floor)."""
MAX_PEOPLE = 64
NEAR_M = 0.2
"""Points closer than this to a camera's centre (along its axis) are not in its picture."""
IN_FRONT_M = 0.3
"""A person covers another in a picture when nearer to the camera by more than this."""
DOUBLE_SHIFT = 0.3
"""A second box on one person is shifted sideways by this share of its width."""
MIN_BOX_PX = 4.0
"""Boxes narrower or lower than this once clipped to the image are not reported."""


@dataclass(frozen=True, slots=True)
class DetectorModel:
    """How the simulated detector errs (probabilities, and box noise relative to the box height)."""

    p_detect: float = 0.92
    """Chance of finding a person nobody hides."""
    hidden_miss: float = 0.7
    """A person whose box is covered by at least this share is never found."""
    box_noise: float = 0.03
    """1-sigma noise of each box edge, relative to the box height."""
    clutter_per_frame: float = 0.3
    """Mean false boxes per camera and frame."""
    double_prob: float = 0.02
    """Chance that a found person gets a second, shifted box."""


@dataclass(frozen=True, slots=True)
class RoomCameras:
    """Perspective cameras high in the room's corners, each looking at the room's centre."""

    height_m: float = 2.6
    image_size: tuple[int, int] = (640, 480)
    hfov_deg: float = 90.0
    inset_m: float = 0.2
    """How far inside each corner a camera hangs."""


def _look_at(centre: FloatArray, target: FloatArray) -> FloatArray:
    """World -> camera rotation of a camera at ``centre`` looking at ``target`` (x right, y down, z ahead)."""
    z = target - centre
    z = z / np.linalg.norm(z)
    x = np.cross(z, np.array([0.0, 0.0, 1.0]))
    x = x / np.linalg.norm(x)
    y = np.cross(z, x)
    return np.stack([x, y, z])


def _cameras(
    room_x_m: float, room_y_m: float, cams: RoomCameras
) -> list[tuple[str, FloatArray, FloatArray, FloatArray]]:
    """(id, K, R, centre) of the four corner cameras."""
    w, h = cams.image_size
    f = 0.5 * w / math.tan(math.radians(cams.hfov_deg) / 2)
    k = np.array([[f, 0.0, w / 2], [0.0, f, h / 2], [0.0, 0.0, 1.0]])
    target = np.array([room_x_m / 2, room_y_m / 2, 0.9])
    i = cams.inset_m
    corners = [(i, i), (room_x_m - i, i), (room_x_m - i, room_y_m - i), (i, room_y_m - i)]
    out = []
    for n, (x, y) in enumerate(corners, start=1):
        c = np.array([x, y, cams.height_m])
        out.append((f"cam{n}", k, _look_at(c, target), c))
    return out


def _project(k: FloatArray, r: FloatArray, c: FloatArray, p: FloatArray) -> FloatArray | None:
    """Pixel (u, v) and depth of world point ``p``; None behind the camera."""
    q = r @ (p - c)
    if q[2] <= NEAR_M:
        return None
    return np.array([k[0, 0] * q[0] / q[2] + k[0, 2], k[1, 1] * q[1] / q[2] + k[1, 2], q[2]])


def _box(k: FloatArray, r: FloatArray, c: FloatArray, xy: FloatArray, height_m: float) -> FloatArray | None:
    """(left, top, right, bottom, depth) of a person standing at ``xy``, or None if behind the camera."""
    feet = _project(k, r, c, np.array([xy[0], xy[1], 0.0]))
    head = _project(k, r, c, np.array([xy[0], xy[1], height_m]))
    if feet is None or head is None:
        return None
    half = k[0, 0] * PERSON_HALF_WIDTH_M / feet[2]
    return np.array([feet[0] - half, head[1], feet[0] + half, feet[1], feet[2]])


def _covered(box: FloatArray, nearer: list[FloatArray]) -> tuple[float, float]:
    """Share of ``box`` covered by the ``nearer`` boxes (union, on a coarse grid), and the highest row where
    a nearer box covers its lower part (the cut)."""
    left, top, right, bottom = box[:4]
    if right - left <= 0 or bottom - top <= 0 or not nearer:
        return 0.0, float(bottom)
    us = np.linspace(left, right, 12)
    vs = np.linspace(top, bottom, 24)
    gu, gv = np.meshgrid(us, vs)
    hid = np.zeros_like(gu, dtype=bool)
    cut = float(bottom)
    for o in nearer:
        inside = (gu >= o[0]) & (gu <= o[2]) & (gv >= o[1]) & (gv <= o[3])
        hid |= inside
        if o[0] < right and o[2] > left and o[1] < bottom:
            cut = min(cut, max(float(o[1]), float(top)))
    return float(hid.mean()), cut


def write_room_dataset(
    out: str | Path,
    *,
    room_m: tuple[float, float] = (8.0, 6.0),
    people: int = 10,
    fps: float = 4.0,
    duration_s: float = 90.0,
    seed: int = 1,
    detector: DetectorModel | None = None,
    cameras: RoomCameras | None = None,
    enter_leave: bool = True,
) -> Path:
    """Write a simulated corner-camera detection dataset into ``out`` (``calib/``, ``detections/``, ``gt.csv``).

    Returns:
        ``out``.

    Raises:
        ConfigError: a room, rate or duration that is not positive, or too many people.
    """
    det = detector if detector is not None else DetectorModel()
    cams_spec = cameras if cameras is not None else RoomCameras()
    rx, ry = room_m
    if not (rx > 0 and ry > 0 and fps > 0 and duration_s > 0 and 0 <= people <= MAX_PEOPLE):
        raise ConfigError(
            f"a room dataset needs a positive room, fps and duration and 0-{MAX_PEOPLE} people, got room {room_m}, "
            f"fps {fps}, duration {duration_s} s, {people} people"
        )
    spec = WorldSpec(room_x_m=rx, room_y_m=ry, people=people, enter_leave=enter_leave, pause_prob=0.2)
    door_w = min(1.2, 0.5 * rx)
    x1 = rx - min(1.0, 0.15 * rx)
    walkers = WalkerSim(spec, seed, lambda _t: (), Door(x0_m=x1 - door_w, x1_m=x1))
    heights = [look.height_m for look in walkers.looks]
    cams = _cameras(rx, ry, cams_spec)
    rng = np.random.default_rng(seed)
    lines: dict[str, list[str]] = {cid: [] for cid, *_ in cams}
    gt = ["frame,id,x_m,y_m"]
    visit = [0] * people
    inside = [False] * people
    for f in range(1, round(duration_s * fps) + 1):
        s = walkers.sample((f - 1) / fps)
        here = [i for i in range(people) if s.present[i] and 0 <= s.x_m[i] <= rx and 0 <= s.y_m[i] <= ry]
        for i in range(people):
            if i in here and not inside[i]:
                visit[i] += 1  # each stay in the room is one ground-truth identity: nobody can tell it is them back
            inside[i] = i in here
        gt += [f"{f},{i + 1}.{visit[i]},{s.x_m[i]:.3f},{s.y_m[i]:.3f}" for i in here]
        floor = {i: np.array([s.x_m[i], s.y_m[i]]) for i in here}
        for cid, k, r, c in cams:
            shot = _Shot(f, (k, r, c), cams_spec.image_size, room_m)
            lines[cid] += _detect(shot, floor, heights, det, rng)
    root = Path(out)
    for sub in ("calib", "detections"):
        (root / sub).mkdir(parents=True, exist_ok=True)
    w_px, h_px = cams_spec.image_size
    for cid, k, r, c in cams:
        calib = {"model": "pinhole", "image_size": [w_px, h_px], "K": k.tolist(), "dist": [], "R": r.tolist()}
        calib["t"] = (-r @ c).tolist()
        (root / "calib" / f"{cid}.json").write_text(json.dumps(calib), encoding="utf-8")
        (root / "detections" / f"{cid}.txt").write_text("\n".join(lines[cid]) + "\n", encoding="utf-8")
    (root / "gt.csv").write_text("\n".join(gt) + "\n", encoding="utf-8")
    return root


@dataclass(frozen=True, slots=True)
class _Shot:
    """What one camera's detector works with at one frame."""

    frame: int
    camera: tuple[FloatArray, FloatArray, FloatArray]
    """(K, R, centre) of the camera."""
    size: tuple[int, int]
    room_m: tuple[float, float]


def _detect(
    shot: _Shot, floor: dict[int, FloatArray], heights: list[float], det: DetectorModel, rng: np.random.Generator
) -> list[str]:
    """One camera's MOT rows of one frame: the people at ``floor`` (person -> x, y) as the detector finds them,
    and its false boxes."""
    k, r, c = shot.camera
    frame, size, room_m = shot.frame, shot.size, shot.room_m
    rows: list[str] = []
    seen = {i: b for i, xy in floor.items() if (b := _box(k, r, c, xy, heights[i])) is not None}
    for i, b in seen.items():
        share, cut = _covered(b, [o for j, o in seen.items() if j != i and o[4] < b[4] - IN_FRONT_M])
        if share >= det.hidden_miss:
            continue
        visible = 1.0 - share / det.hidden_miss
        if rng.random() > det.p_detect * visible:
            continue
        left, top, right = float(b[0]), float(b[1]), float(b[2])
        edges = [v + rng.normal(0.0, det.box_noise * (cut - top)) for v in (left, top, right, cut)]
        score = float(np.clip(0.55 + 0.4 * visible + rng.normal(0.0, 0.08), 0.05, 0.99))
        rows += _row(frame, edges, score, size)
        if rng.random() < det.double_prob:
            shift = float(rng.choice([-1.0, 1.0])) * DOUBLE_SHIFT * (right - left)
            rows += _row(frame, [edges[0] + shift, edges[1], edges[2] + shift, edges[3]], 0.7 * score, size)
    for _ in range(int(rng.poisson(det.clutter_per_frame))):
        xy = np.array([rng.uniform(0.0, room_m[0]), rng.uniform(0.0, room_m[1])])
        b = _box(k, r, c, xy, float(rng.uniform(1.0, 1.9)))
        if b is not None:
            rows += _row(frame, [float(v) for v in b[:4]], float(rng.uniform(0.2, 0.7)), size)
    return rows


def _row(frame: int, edges: list[float], score: float, size: tuple[int, int]) -> list[str]:
    """The MOT row of a box clipped to the image ([] when too little of it is inside)."""
    left, top = max(edges[0], 0.0), max(edges[1], 0.0)
    right, bottom = min(edges[2], float(size[0])), min(edges[3], float(size[1]))
    if right - left < MIN_BOX_PX or bottom - top < MIN_BOX_PX:
        return []
    return [f"{frame},-1,{left:.1f},{top:.1f},{right - left:.1f},{bottom - top:.1f},{score:.3f},-1,-1,-1"]
