"""Synthetic Features for testing and benchmarking the pure fusion (a test harness, not the simulator).

Known people and cameras are projected into the messages a panoramic sensor
node would publish: head bearings, angular widths, top/bottom elevations,
colour histograms and sightings of other robots' cylinder bodies (Eq. 3
boundaries), each with Gaussian noise. Nearer people hide farther ones whose
heads fall within the nearer blob (occlusion), as a real camera would.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from common.angles import wrap_angle
from common.arrays import BoolArray, FloatArray, IntArray
from common.schema import Blob, Features, PanoramicModel, Pose, SensorInfo, Sighting
from resource_manager.ingest.align import Aligned, AlignParams, align
from resource_manager.ingest.buffers import SensorBuffer
from resource_manager.track.tracker import TrackSnapshot
from resource_manager.views.blobs import ImageBounds, Views, stack_histograms


@dataclass
class Cam:
    id: str
    x: float
    y: float
    z: float = 1.1
    yaw: float = 0.0
    mobile: bool = False
    surveyed: bool = True
    radius: float = 0.18
    sigma_rad: float = math.radians(0.2)
    max_range_m: float = 30.0
    sights: bool = True
    """False: this camera reports no sightings of other robots (e.g. a node without body detection)."""


@dataclass
class Person:
    x: float
    y: float
    height: float = 1.75
    width: float = 0.45
    hist: list[float] = field(default_factory=list)


def colour_hist(k: int, bins: int = 16) -> list[float]:
    """A distinct, smooth histogram for person k."""
    c = (k * 0.618034 * bins) % bins  # golden-ratio spacing: neighbours in k get distant colours
    h = np.exp(-0.5 * ((np.arange(bins) - c) / 1.5) ** 2) + 0.02
    return list(h / h.sum())


def info_for(cam: Cam, seq: int = 0, stamp_ns: int = 1) -> SensorInfo:
    pose = Pose(x_m=cam.x, y_m=cam.y, z_m=cam.z, yaw_rad=wrap_angle(cam.yaw)) if cam.surveyed else None
    return SensorInfo(
        sensor_id=cam.id,
        seq=seq,
        stamp_ns=stamp_ns,
        kind="panoramic",
        model=PanoramicModel(width_px=1800, height_px=162, f_v_px=256.0, v0_px=93.0),
        pose=pose,
        pose_source="surveyed" if cam.surveyed else "mutual",
        mobile=cam.mobile,
        body_radius_m=cam.radius,
        bearing_sigma_rad=cam.sigma_rad,
    )


def features_for(
    cam: Cam,
    people: list[Person],
    cams: list[Cam],
    t_ns: int,
    seq: int,
    rng: np.random.Generator,
    *,
    bearing_noise_rad: float | None = None,
    boundary_noise_rad: float | None = None,
    occlusion: bool = True,
    hist_noise: float = 0.01,
    id_offset: int = 0,
) -> Features:
    """What ``cam`` would report at ``t_ns``: one blob per visible person (local_id = person index + offset)."""
    sb = cam.sigma_rad if bearing_noise_rad is None else bearing_noise_rad
    bn = cam.sigma_rad if boundary_noise_rad is None else boundary_noise_rad
    seen = []
    for k, p in enumerate(people):
        dx, dy = p.x - cam.x, p.y - cam.y
        d = math.hypot(dx, dy)
        if d < 0.3 or d > cam.max_range_m:
            continue
        seen.append((d, k, p, math.atan2(dy, dx), 2 * math.atan(p.width / (2 * d))))
    seen.sort(key=lambda s: s[0])
    blobs: list[Blob] = []
    kept: list[tuple[float, float]] = []
    for d, k, p, az, w in seen:
        if occlusion and any(abs(wrap_angle(az - a)) < 0.5 * (w + wk) * 0.6 for a, wk in kept):
            continue
        kept.append((az, w))
        h = np.asarray(p.hist or colour_hist(k)) + rng.normal(0.0, hist_noise, len(p.hist or colour_hist(k)))
        h = np.clip(h, 1e-4, None)
        h = h / h.sum()
        blobs.append(
            Blob(
                local_id=k + id_offset,
                bearing_rad=wrap_angle(az - cam.yaw + rng.normal(0.0, sb)),
                width_rad=max(1e-3, w * (1 + rng.normal(0.0, 0.03))),
                top_elev_rad=math.atan2(p.height - cam.z, d) + rng.normal(0.0, sb),
                bottom_elev_rad=math.atan2(-cam.z, d),
                bbox_u_px=0.0,
                bbox_v_px=10.0,  # not at the upper border: heads are never cut here
                bbox_w_px=10.0,
                bbox_h_px=30.0,
                hist=[float(v) for v in h],
            )
        )
    sightings: list[Sighting] = []
    for other in cams if cam.sights else []:
        if other.id == cam.id or other.radius <= 0:
            continue
        dx, dy = other.x - cam.x, other.y - cam.y
        d = math.hypot(dx, dy)
        if d <= other.radius * 1.05 or d > cam.max_range_m:
            continue
        beta = math.atan2(dy, dx) - cam.yaw
        half = math.asin(other.radius / d)
        left = wrap_angle(beta + half + rng.normal(0.0, bn))
        right = wrap_angle(beta - half + rng.normal(0.0, bn))
        alpha = abs(wrap_angle(left - right))
        sightings.append(
            Sighting(
                target_id=other.id,
                left_rad=left,
                right_rad=right,
                alpha_rad=alpha,
                bearing_rad=wrap_angle(right + wrap_angle(left - right) / 2),
                distance_m=other.radius / math.sin(alpha / 2),
                body_radius_m=other.radius,
            )
        )
    return Features(sensor_id=cam.id, seq=seq, stamp_ns=t_ns, frame_index=seq, blobs=blobs, sightings=sightings)


def rectangle_path(
    t_s: float, rect: tuple[float, float, float, float], speed: float, phase: float = 0.0
) -> tuple[float, float]:
    """Position on a rectangular loop walked at ``speed`` (the paper's Fig. 7 experiment)."""
    x0, y0, x1, y1 = rect
    w, h = x1 - x0, y1 - y0
    per = 2 * (w + h)
    s = (speed * t_s + phase * per) % per
    if s < w:
        return x0 + s, y0
    s -= w
    if s < h:
        return x1, y0 + s
    s -= h
    if s < w:
        return x1 - s, y1
    s -= w
    return x0, y1 - s


def mota(
    gt: list[dict[int, tuple[float, float]]], hyp: list[dict[str, tuple[float, float]]], thr_m: float = 0.5
) -> dict[str, float]:
    """CLEAR-MOT MOTA with a distance threshold, Hungarian matching per frame, keeping previous matches."""
    from scipy.optimize import linear_sum_assignment

    fn = fp = idsw = 0
    n_gt = 0
    prev: dict[int, str] = {}
    dists = []
    for g, h in zip(gt, hyp, strict=True):
        n_gt += len(g)
        matched: dict[int, str] = {}
        gids, hids = list(g), list(h)
        # keep previous correspondences that are still within threshold
        for gid, hid in prev.items():
            if gid in g and hid in h and math.dist(g[gid], h[hid]) < thr_m:
                matched[gid] = hid
        rg = [x for x in gids if x not in matched]
        rh = [x for x in hids if x not in matched.values()]
        if rg and rh:
            c = np.array([[math.dist(g[a], h[b]) for b in rh] for a in rg])
            c = np.where(c < thr_m, c, 1e6)
            ri, ci = linear_sum_assignment(c)
            for i, j in zip(ri, ci, strict=True):
                if c[i, j] < thr_m:
                    gid, hid = rg[i], rh[j]
                    if gid in prev and prev[gid] != hid:
                        idsw += 1
                    matched[gid] = hid
        for gid, hid in matched.items():
            dists.append(math.dist(g[gid], h[hid]))
        fn += len(g) - len(matched)
        fp += len(h) - len(matched)
        prev.update(matched)
    return {
        "mota": 1.0 - (fn + fp + idsw) / max(n_gt, 1),
        "fn": fn,
        "fp": fp,
        "idsw": idsw,
        "mean_error_m": float(np.mean(dists)) if dists else math.nan,
    }


class RandomWalk:
    """People walking between random waypoints of a room at their own speeds (seeded)."""

    def __init__(self, n: int, room: tuple[float, float, float, float], seed: int, margin: float = 0.6) -> None:
        rng = np.random.default_rng(seed)
        self.legs: list[list[tuple[float, float, float, float, float]]] = []
        x0, y0, x1, y1 = room[0] + margin, room[1] + margin, room[2] - margin, room[3] - margin
        self.heights = [float(h) for h in rng.uniform(1.55, 1.9, n)]
        for _ in range(n):
            legs = []
            t = 0.0
            p = (float(rng.uniform(x0, x1)), float(rng.uniform(y0, y1)))
            speed = float(rng.uniform(0.5, 1.5))
            while t < 3600.0 and len(legs) < 400:
                q = (float(rng.uniform(x0, x1)), float(rng.uniform(y0, y1)))
                dur = math.dist(p, q) / speed
                legs.append((t, t + dur, *p, *q))  # type: ignore[arg-type]
                t += dur
                p = q
            self.legs.append(legs)  # type: ignore[arg-type]

    def at(self, t_s: float) -> list[Person]:
        out = []
        for k, legs in enumerate(self.legs):
            for leg in legs:
                ta, tb, xa, ya, xb, yb = leg  # type: ignore[misc]
                if ta <= t_s <= tb:
                    f = (t_s - ta) / max(tb - ta, 1e-9)
                    out.append(Person(xa + f * (xb - xa), ya + f * (yb - ya), self.heights[k]))
                    break
            else:
                out.append(Person(legs[-1][4], legs[-1][5], self.heights[k]))  # type: ignore[misc]
        return out


def aligned_of(frames: Sequence[Features]) -> Aligned:
    """The blobs of one frame per sensor as alignment gives them at the frames' (common) stamp: held as they are."""
    return align(
        [(f.sensor_id, SensorBuffer(capacity=2, stamps=[f.stamp_ns], frames=[f]), AlignParams()) for f in frames],
        frames[0].stamp_ns,
    )


@dataclass(frozen=True)
class ViewSpec:
    """One camera's blobs in world terms, for tests: :func:`stack_views` puts several into the tick's
    :class:`~resource_manager.views.blobs.Views` (what the manager's views stage builds from aligned blobs)."""

    sensor_id: str
    origin_xy: FloatArray
    z_m: float
    sigma_rad: float
    bearing_rad: FloatArray
    width_rad: FloatArray
    top_elev_rad: FloatArray
    hist: FloatArray | None
    """(n, k) L1-normalised histograms (None: none sent)."""
    local_id: IntArray
    bottom_elev_rad: FloatArray | None = None
    fov: tuple[float, float] | None = None
    mono_range_m: FloatArray | None = None
    mono_sigma_m: FloatArray | None = None
    top_cut: BoolArray | None = None
    side_cut: FloatArray | None = None
    sigma_xy_m: float = 0.0
    point_var_m2: float = 0.0
    period_s: float = 0.0
    image: ImageBounds | None = None
    body_radius_m: float = 0.0
    confidence: FloatArray | None = None
    blobs_merge: bool = False
    shared_detector: str = ""

    @property
    def n(self) -> int:
        return len(self.bearing_rad)


def stack_views(specs: Sequence[ViewSpec]) -> Views:
    """The tick's views of ``specs`` (in their order)."""
    counts = [v.n for v in specs]
    offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)

    def cat(get: str, fill: float) -> FloatArray:
        parts = [np.full(v.n, fill) if getattr(v, get) is None else np.asarray(getattr(v, get), float) for v in specs]
        return np.concatenate(parts) if parts else np.zeros(0)

    roots = [None if v.hist is None or not v.n else np.sqrt(np.clip(v.hist, 0.0, None)) for v in specs]
    bins, hist_sqrt = stack_histograms(roots, offsets)
    return Views(
        sensor_ids=tuple(v.sensor_id for v in specs),
        offsets=offsets,
        origin=np.array([v.origin_xy for v in specs], dtype=np.float64).reshape(-1, 2),
        z_m=np.array([v.z_m for v in specs], dtype=np.float64),
        sigma_rad=np.array([v.sigma_rad for v in specs], dtype=np.float64),
        sigma_xy_m=np.array([v.sigma_xy_m for v in specs], dtype=np.float64),
        point_var_m2=np.array([v.point_var_m2 for v in specs], dtype=np.float64),
        period_s=np.array([v.period_s for v in specs], dtype=np.float64),
        body_radius_m=np.array([v.body_radius_m for v in specs], dtype=np.float64),
        blobs_merge=np.array([v.blobs_merge for v in specs], dtype=bool),
        shared_detector=tuple(v.shared_detector for v in specs),
        fov=tuple(v.fov for v in specs),
        image=tuple(v.image for v in specs),
        hist_bins=bins,
        bearing_rad=cat("bearing_rad", 0.0),
        width_rad=cat("width_rad", 0.0),
        top_elev_rad=cat("top_elev_rad", 0.0),
        bottom_elev_rad=cat("bottom_elev_rad", math.nan),
        top_cut=cat("top_cut", 0.0) > 0,
        side_cut=cat("side_cut", 0.0),
        mono_range_m=cat("mono_range_m", math.nan),
        mono_sigma_m=cat("mono_sigma_m", math.nan),
        local_id=np.concatenate([np.asarray(v.local_id, np.int64) for v in specs]) if specs else np.zeros(0, np.int64),
        confidence=cat("confidence", 1.0),
        hist_sqrt=hist_sqrt,
    )


def view(
    sid: str,
    origin: tuple[float, float],
    targets: list[tuple[float, float, float, int | None]],
    z: float = 1.1,
    *,
    sigma_deg: float = 0.2,
    feet_sigma_m: float | None = None,
) -> ViewSpec:
    """Blobs seen from ``origin`` of targets (x, y, height, colour index; None for all: a view without colour),
    exact; with ``feet_sigma_m``, each box's foot gives the target's floor distance with that uncertainty."""
    o = np.array(origin, dtype=np.float64)
    b, w, top, bottom, dist, hist = [], [], [], [], [], []
    for x, y, h, k in targets:
        d = math.hypot(x - o[0], y - o[1])
        b.append(math.atan2(y - o[1], x - o[0]))
        w.append(2 * math.atan(0.45 / (2 * d)))
        top.append(math.atan2(h - z, d))
        bottom.append(math.atan2(-z, d))
        dist.append(d)
        if k is not None:
            hist.append(colour_hist(k))
    feet = {}
    if feet_sigma_m is not None:
        feet = {
            "bottom_elev_rad": np.array(bottom),
            "mono_range_m": np.array(dist),
            "mono_sigma_m": np.full(len(dist), feet_sigma_m),
        }
    return ViewSpec(
        sensor_id=sid,
        origin_xy=o,
        z_m=z,
        sigma_rad=math.radians(sigma_deg),
        bearing_rad=np.array(b),
        width_rad=np.array(w),
        top_elev_rad=np.array(top),
        hist=np.array(hist) if hist else None,
        local_id=np.arange(len(targets)),
        **feet,
    )


def snapshot(
    serial: int = 1, at: tuple[float, float] = (0.0, 0.0), *, track_id: str = "m-1", **fields: object
) -> TrackSnapshot:
    """A track as the other stages read it: by default a published person standing at ``at``, seen now; ``fields``
    override any other field (a tentative one: ``track_id=""``)."""
    confirmed = bool(track_id)
    base: dict[str, object] = {
        "serial": serial,
        "track_id": track_id,
        "x": np.array([at[0], at[1], 0.0, 0.0]),
        "p_xy": np.eye(2) * 0.01,
        "height_m": 1.7,
        "existence": 0.99 if confirmed else 0.6,
        "state": "confirmed" if confirmed else "tentative",
        "method": "least_squares",
        "sensors": (),
        "views": (),
        "predicted_error_m": 0.1,
        "born_ns": 0,
        "t_ns": 0,
        "hits": 10,
        "misses": 0,
        "confirmed": confirmed,
        "detected": True,
        "placed": True,
        "reported": confirmed,
    }
    return TrackSnapshot(**{**base, **fields})  # type: ignore[arg-type]
