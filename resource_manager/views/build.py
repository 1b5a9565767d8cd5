"""World-frame views of the cameras at the fusion instant: what the tracker works on.

Every aligned sensor with a known pose becomes a view of the tick's :class:`~resource_manager.views.blobs.Views`,
built here once per tick: bearings rotated into the world (``yaw + bearing``), the sensor's bearing error plus its
pose's yaw error, the floor distance of each blob whose feet a perspective camera sees
(:mod:`~resource_manager.views.mono`), the camera's picture (to know whom it can see) and frame period, and no blob
that is a known robot or tripod body seen by another camera (known bodies are not people).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Collection, Mapping
from dataclasses import dataclass
from itertools import chain

import numpy as np

from common.angles import wrap_angle
from common.arrays import BoolArray, FloatArray, IntArray
from common.schema import PinholeModel, SensorInfo
from resource_manager.ingest.align import Aligned
from resource_manager.poses.solver import PoseEstimate
from resource_manager.track.model import HEAD_HEIGHT_M, HEAD_HEIGHT_SIGMA_M
from resource_manager.views.blobs import ImageBounds, Views, stack_histograms
from resource_manager.views.mono import mono_ranges

__all__ = [
    "BODY_TOP_MARGIN_M",
    "FeetModel",
    "build_views",
    "image_bounds",
    "pinhole_fov",
]

TOP_CUT_PX = 0.5
"""A blob whose box starts this close to the image's upper border has its head cut off (too close)."""
BODY_TOP_MARGIN_M = 0.2
"""A blob on a robot body's bearing whose top is below the robot's camera + this is the body, not a person."""
FEET_CUT_PX = 2.0
"""A box whose bottom is this close to the image's lower border does not show the feet."""
SIDE_CUT_PX = 2.0
"""A box whose left or right edge is this close to the picture's side is cut by it: not the person's whole width."""

DOWNWARD_AXIS_Z = 0.9
"""A perspective camera whose optical axis has a vertical component above this (cos 26 deg) looks nearly
straight down: it sees every azimuth around its foot."""


@dataclass(frozen=True, slots=True)
class FeetModel:
    """How perspective cameras' box bottoms (the feet) turn into floor distances (:mod:`.mono`)."""

    sigma_elev_rad: float
    """1-sigma error of a box bottom's elevation."""
    base_sigma_m: float
    """Added to every floor-distance sigma: the feet are not exactly below the point tracked."""
    max_range_m: float
    """Farther than this a floor distance is not used."""
    height_m: tuple[float, float] = (HEAD_HEIGHT_M, HEAD_HEIGHT_SIGMA_M)
    """People's head-top heights (mean, spread): a box whose distance from its bottom and whose top put the head
    at no person's height does not show the feet (someone nearer, or the picture's edge, cut it above them)."""


def build_views(
    aligned: Aligned,
    poses: dict[str, PoseEstimate],
    infos: Mapping[str, SensorInfo],
    sigma_of: Callable[[str], float],
    *,
    feet: FeetModel | None = None,
    point_sigma_m: float = 0.0,
    skip: Collection[str] = (),
) -> Views:
    """World-frame blobs of every aligned sensor whose pose is known, in order of sensor ids.

    Args:
        aligned: every sensor's blobs at the fusion instant.
        poses: the known poses.
        infos: every sensor's SensorInfo (camera model, frame rate, body radius, point spread).
        sigma_of: a sensor's bearing sigma.
        feet: how perspective cameras' box bottoms give floor distances (None: they give none).
        point_sigma_m: the spread of a sensor's measured point around a person's floor position, for a sensor
            whose SensorInfo states none.
        skip: sensors that give no view at this instant (a robot that has not settled).
    """
    order = sorted((sid, i) for i, sid in enumerate(aligned.sensor_ids) if sid in poses and sid not in skip)
    if not order:
        return Views.empty()
    sids = [sid for sid, _ in order]
    pose_of = [poses[sid] for sid in sids]
    sigmas = [math.hypot(sigma_of(sid), pose.sigma_yaw_rad) for sid, pose in zip(sids, pose_of, strict=True)]
    rows = [i for _, i in order]
    take = _gather(aligned, rows)
    tab = aligned.values if take is None else aligned.values[take]
    view_of = np.repeat(np.arange(len(order), dtype=np.int64), aligned.counts[rows])
    bodies = {sid: info.body_radius_m for sid, info in infos.items() if info.body_radius_m > 0}
    keep = _not_bodies(sids, pose_of, tab, view_of=view_of, sigmas=sigmas, bodies=bodies, poses=poses)
    if not keep.all():
        take = np.flatnonzero(keep) if take is None else take[keep]
        view_of, tab = view_of[keep], tab[keep]
    offsets = np.concatenate([[0], np.cumsum(np.bincount(view_of, minlength=len(sids)))]).astype(np.int64)
    hists = aligned.hist if take is None else [aligned.hist[e] for e in take.tolist()]
    hist_bins, hist_sqrt = _histograms_of(hists, offsets)
    cams = _Cameras.of(sids, infos, point_sigma_m)
    mono_range, mono_sigma = np.full(len(tab), math.nan), np.full(len(tab), math.nan)
    for i, (pose, sigma, model) in enumerate(zip(pose_of, sigmas, cams.models, strict=True)):
        sl = slice(int(offsets[i]), int(offsets[i + 1]))
        got = _mono(tab[sl], pose, sigma, model, feet)
        if got is not None:
            mono_range[sl], mono_sigma[sl] = got
    return Views(
        sensor_ids=tuple(sids),
        offsets=offsets,
        origin=np.array([pose.origin for pose in pose_of], dtype=np.float64).reshape(-1, 2),
        z_m=np.array([pose.z_m for pose in pose_of], dtype=np.float64),
        sigma_rad=np.array(sigmas, dtype=np.float64),
        sigma_xy_m=np.array([pose.sigma_xy_m for pose in pose_of], dtype=np.float64),
        point_var_m2=cams.point_var_m2,
        period_s=cams.period_s,
        body_radius_m=cams.body_radius_m,
        blobs_merge=cams.blobs_merge,
        shared_detector=cams.shared_detector,
        fov=cams.fov,
        image=cams.image,
        hist_bins=hist_bins,
        bearing_rad=tab[:, 0] + np.array([pose.yaw_rad for pose in pose_of], dtype=np.float64)[view_of],
        width_rad=tab[:, 1],
        top_elev_rad=tab[:, 2],
        bottom_elev_rad=tab[:, 3],
        top_cut=(tab[:, 5] >= 0.0) & (tab[:, 5] <= TOP_CUT_PX),
        side_cut=_side_cut(tab, view_of, cams.models),
        mono_range_m=mono_range,
        mono_sigma_m=mono_sigma,
        local_id=aligned.local_id if take is None else aligned.local_id[take],
        confidence=tab[:, 6],
        hist_sqrt=hist_sqrt,
    )


def _side_cut(tab: FloatArray, view_of: IntArray, models: list[PinholeModel | None]) -> FloatArray:
    """(m,) :attr:`Views.side_cut` of the blobs (rows of ``tab``, in views ``view_of``) of each perspective camera
    ``models`` (None: panoramic, never cut)."""
    out = np.zeros(len(tab))
    left_cut = tab[:, 7] <= SIDE_CUT_PX
    for i, model in enumerate(models):
        if model is None:
            continue
        r = np.asarray(model.r, dtype=np.float64).reshape(3, 3)
        # The world-bearing way of the picture's right: the z of (optical axis x image right), both in the world.
        right = float(np.sign(r[2, 0] * r[0, 1] - r[2, 1] * r[0, 0]))
        mine = view_of == i
        right_cut = tab[:, 8] >= model.width_px - SIDE_CUT_PX
        # A box cut on both sides (a person filling the picture) keeps its centre: nothing says which way.
        out[mine & left_cut & ~right_cut] = -right
        out[mine & right_cut & ~left_cut] = right
    return out


def _gather(aligned: Aligned, rows: list[int]) -> IntArray | None:
    """The blobs (entries of ``aligned``) of its sensors ``rows``, in that order; None: all of them in their order
    (nothing to gather)."""
    if rows == list(range(len(aligned.sensor_ids))):
        return None
    bounds = aligned.offsets.tolist()
    return np.concatenate([np.arange(bounds[i], bounds[i + 1], dtype=np.int64) for i in rows])


@dataclass(frozen=True, slots=True)
class _Cameras:
    """The views' cameras as their SensorInfo describes them (per view)."""

    models: list[PinholeModel | None]
    """Each perspective camera's model (None: another kind)."""
    point_var_m2: FloatArray
    period_s: FloatArray
    body_radius_m: FloatArray
    blobs_merge: BoolArray
    shared_detector: tuple[str, ...]
    fov: tuple[tuple[float, float] | None, ...]
    image: tuple[ImageBounds | None, ...]

    @staticmethod
    def of(sids: list[str], infos: Mapping[str, SensorInfo], point_sigma_m: float) -> _Cameras:
        got = [infos.get(sid) for sid in sids]
        models = [
            info.model
            if info is not None and info.kind in ("pinhole", "ptz") and isinstance(info.model, PinholeModel)
            else None
            for info in got
        ]
        spread = [info.point_sigma_m if info is not None and info.point_sigma_m > 0 else point_sigma_m for info in got]
        return _Cameras(
            models=models,
            point_var_m2=np.array([s * s for s in spread], dtype=np.float64),
            period_s=np.array(
                [1.0 / info.fps if info is not None and info.fps > 0 else 0.0 for info in got], dtype=np.float64
            ),
            body_radius_m=np.array([info.body_radius_m if info is not None else 0.0 for info in got], dtype=np.float64),
            blobs_merge=np.array([info is not None and info.blobs_merge for info in got], dtype=bool),
            shared_detector=tuple(info.shared_detector if info is not None else "" for info in got),
            fov=tuple(pinhole_fov(m) if m is not None else None for m in models),
            image=tuple(image_bounds(m) if m is not None else None for m in models),
        )


def _histograms(hists: list[list[float]]) -> FloatArray | None:
    """The square roots of colour histograms as one (n, bins) array, when they all have the same (non-zero) number
    of bins; else None."""
    hist_lens = {len(h) for h in hists}
    if len(hist_lens) != 1 or next(iter(hist_lens)) <= 0:
        return None
    bins = next(iter(hist_lens))
    hist = np.fromiter(chain.from_iterable(hists), dtype=np.float64, count=bins * len(hists))
    return np.sqrt(np.clip(hist.reshape(-1, bins), 0.0, None))


def _histograms_of(hists: list[list[float]], offsets: IntArray) -> tuple[IntArray, dict[int, FloatArray]]:
    """Each view's histogram size (0: none) and the square-rooted histograms per size (:attr:`Views.hist_sqrt`): all
    at once when every blob has histograms of one size, else view by view."""
    counts = np.diff(offsets)
    every = _histograms(hists)
    if every is not None:
        return np.where(counts > 0, every.shape[1], 0).astype(np.int64), {every.shape[1]: every}
    per_view = [
        _histograms(hists[lo:hi]) if hi > lo else None
        for lo, hi in zip(offsets[:-1].tolist(), offsets[1:].tolist(), strict=True)
    ]
    return stack_histograms(per_view, offsets)


def _mono(
    tab: FloatArray, pose: PoseEstimate, sigma: float, model: PinholeModel | None, feet: FeetModel | None
) -> tuple[FloatArray, FloatArray] | None:
    """Floor distances (and their sigmas) of one perspective view's blobs from their box bottoms (None: the view
    gives none)."""
    if model is None or feet is None:
        return None
    cut = tab[:, 4] >= model.height_px - FEET_CUT_PX
    return mono_ranges(
        np.where(cut, np.nan, tab[:, 3]),
        pose.z_m,
        feet.sigma_elev_rad,
        feet.base_sigma_m,
        feet.max_range_m,
        top_elev_rad=tab[:, 2],
        height_m=feet.height_m,
        sigma_top_rad=sigma,
    )


def _not_bodies(
    sids: list[str],
    pose_of: list[PoseEstimate],
    tab: FloatArray,
    *,
    view_of: IntArray,
    sigmas: list[float],
    bodies: dict[str, float] | None,
    poses: dict[str, PoseEstimate],
) -> BoolArray:
    """(n,) False for the blobs (rows of ``tab``, of the views ``view_of``: cameras ``sids`` at ``pose_of``) that are a
    known robot/tripod body seen by another camera.

    A blob on a body's bearing, about its angular width, whose top is below the body's camera (plus
    :data:`BODY_TOP_MARGIN_M`) is that body; a person behind it shows a taller top.
    """
    body_list = [(sid, r) for sid, r in (bodies or {}).items() if r > 0 and sid in poses]
    keep = np.ones(tab.shape[0], dtype=bool)
    if not body_list or not tab.shape[0]:
        return keep
    bx = np.array([poses[o].x_m for o, _ in body_list])
    by = np.array([poses[o].y_m for o, _ in body_list])
    bz = np.array([poses[o].z_m for o, _ in body_list])
    radius = np.array([r for _, r in body_list])
    vx = np.array([pose.x_m for pose in pose_of])[:, None]
    vy = np.array([pose.y_m for pose in pose_of])[:, None]
    vz = np.array([pose.z_m for pose in pose_of])[:, None]
    yaw = np.array([pose.yaw_rad for pose in pose_of])[:, None]
    sig = np.array(sigmas)[:, None]
    ox, oy, oz = bx - vx, by - vy, bz - vz  # (views, bodies)
    dist = np.hypot(ox, oy)
    ok = (dist > radius) & (np.array(sids)[:, None] != np.array([o for o, _ in body_list]))
    half = np.arcsin(np.where(ok, radius / np.maximum(dist, 1e-9), 0.0))
    az = np.arctan2(oy, ox) - yaw
    # The body ends at the other camera (on its axis); a person behind it shows a taller top.
    body_top = np.arctan2(oz + BODY_TOP_MARGIN_M, np.maximum(dist, 1e-9))
    v, s = view_of, sig[view_of]
    is_body = (
        ok[v]
        & (np.abs(wrap_angle(tab[:, 0, None] - az[v])) < half[v] + 3 * s)
        & (tab[:, 1, None] < 3.0 * half[v] + 6 * s)
        & (tab[:, 2, None] < body_top[v])
    )
    keep &= ~np.any(is_body, axis=1)
    return keep


def image_bounds(model: PinholeModel) -> ImageBounds:
    """The picture of a perspective camera (its ideal projection and size)."""
    return ImageBounds(
        k=np.asarray(model.k, dtype=np.float64).reshape(3, 3),
        r=np.asarray(model.r, dtype=np.float64).reshape(3, 3),
        t=np.asarray(model.t_m, dtype=np.float64).reshape(3),
        width_px=model.width_px,
        height_px=model.height_px,
    )


def pinhole_fov(model: PinholeModel, margin_rad: float = 0.05) -> tuple[float, float] | None:
    """(world azimuth of the optical axis, horizontal half field of view) of a perspective camera.

    None when the camera looks nearly straight down (it then sees every azimuth around its foot).
    """
    r, k = model.r, model.k
    axis_x, axis_y, axis_z = r[6], r[7], r[8]  # the camera z axis in the world: third row of R
    if abs(axis_z) > DOWNWARD_AXIS_Z or k[0] <= 0:
        return None
    half = math.atan(max(k[2], model.width_px - k[2]) / k[0]) / max(math.sqrt(axis_x**2 + axis_y**2), 0.3)
    return math.atan2(axis_y, axis_x), min(half + margin_rad, math.pi)
