"""World-frame views of the cameras at the fusion instant, and "who sees something toward (x, y)".

Each aligned sensor with a known pose becomes a :class:`~resource_manager.match.ViewBlobs`: bearings
rotated into the world (``yaw + bearing``), the sensor's bearing error plus its pose's yaw error, and
blobs that are a known robot/tripod body seen by another camera removed (known bodies are not people).
:class:`AllBlobs` flattens every view's blobs so the ghost checks can ask, for a position, how many of the
cameras that could see it (in range, in their field of view) have a blob toward it.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from itertools import chain

import numpy as np
import numpy.typing as npt

from common.schema import PinholeModel, SensorInfo
from resource_manager.config import MatchSection
from resource_manager.ingest.align import AlignedBlob, AlignedView
from resource_manager.match import ViewBlobs
from resource_manager.mono import mono_ranges
from resource_manager.poses.solver import PoseEstimate

TOP_CUT_PX = 0.5
"""A blob whose box starts this close to the image's upper border has its head cut off (too close)."""

__all__ = [
    "BODY_TOP_MARGIN_M",
    "AllBlobs",
    "build_views",
    "mono_cameras",
    "perspective_fovs",
    "pinhole_fov",
    "subset_view",
    "wrap",
]

FloatArray = npt.NDArray[np.float64]
TWO_PI = 2.0 * math.pi
BODY_TOP_MARGIN_M = 0.2
"""A blob on a robot body's bearing whose top is below the robot's camera + this is the body, not a person."""


def build_views(
    aligned: dict[str, AlignedView],
    poses: dict[str, PoseEstimate],
    sigma_of: Callable[[str], float],
    bodies: dict[str, float] | None = None,
    fovs: dict[str, tuple[float, float]] | None = None,
    *,
    mono: dict[str, tuple[float, float, float, float]] | None = None,
) -> dict[str, ViewBlobs]:
    """World-frame blobs of every aligned sensor whose pose is known.

    Args:
        aligned: every sensor's blobs at the fusion instant.
        poses: the known poses.
        sigma_of: a sensor's bearing sigma.
        bodies: sensor id -> body radius (m) of the robots/tripods; a blob that is one of those bodies seen by
            another camera (same bearing, about its angular size) is dropped: known bodies are not people.
        fovs: sensor id -> (axis azimuth, half width) of perspective cameras (see :func:`pinhole_fov`).
        mono: sensor id -> (feet elevation sigma rad, base sigma m, max range m, image height px) of the
            cameras whose blobs give floor distances (:func:`~resource_manager.mono.mono_ranges`).
    """
    out: dict[str, ViewBlobs] = {}
    entries = [(sid, av.blobs, poses[sid]) for sid, av in aligned.items() if sid in poses]
    if not entries:
        return out
    # Every blob of every view in one table (this runs for every sensor on every tick): one pass in Python,
    # then whole-array operations, each view a slice of the result.
    nan = math.nan
    blobs_all = [b for _, blobs, _ in entries for b in blobs]
    counts = [len(blobs) for _, blobs, _ in entries]
    tab = np.fromiter(  # np.fromiter over one flat stream: ~3x faster than np.array of tuples
        chain.from_iterable(
            (
                b.bearing_rad,
                b.width_rad,
                b.top_elev_rad,
                b.bottom_elev_rad if b.feet_visible else nan,
                b.bottom_px,
                b.top_px,
            )
            for b in blobs_all
        ),
        dtype=np.float64,
        count=6 * len(blobs_all),
    ).reshape(-1, 6)
    view_of = np.repeat(np.arange(len(entries)), counts)
    sigmas = [math.hypot(sigma_of(sid), pose.sigma_yaw_rad) for sid, _, pose in entries]
    keep = _not_bodies(entries, tab, view_of=view_of, sigmas=sigmas, bodies=bodies, poses=poses)
    if not keep.all():
        blobs_all = [b for b, k in zip(blobs_all, keep.tolist(), strict=True) if k]
        tab, view_of = tab[keep], view_of[keep]
        counts = np.bincount(view_of, minlength=len(entries)).tolist()
    yaw = np.array([pose.yaw_rad for _, _, pose in entries], dtype=np.float64)
    bearing_world = tab[:, 0] + yaw[view_of]
    local_id = np.array([b.local_id for b in blobs_all], dtype=np.int64)
    top_cut = (tab[:, 5] >= 0.0) & (tab[:, 5] <= TOP_CUT_PX)
    hist_lens = {len(b.hist) for b in blobs_all}
    hist_all = hist_sqrt_all = None
    if len(hist_lens) == 1 and next(iter(hist_lens)) > 0:
        bins = next(iter(hist_lens))
        hist_all = np.fromiter(
            chain.from_iterable(b.hist for b in blobs_all), dtype=np.float64, count=bins * len(blobs_all)
        ).reshape(-1, bins)
        hist_sqrt_all = np.sqrt(np.clip(hist_all, 0.0, None))
    ends = np.cumsum(counts).tolist()
    for (sid, _, pose), sigma, stop, n in zip(entries, sigmas, ends, counts, strict=True):
        sl = slice(stop - n, stop)
        bottom = tab[sl, 3]
        hist = hist_sqrt = None
        if n and hist_all is not None and hist_sqrt_all is not None:
            hist, hist_sqrt = hist_all[sl], hist_sqrt_all[sl]
        elif n and hist_all is None:
            lens = {len(b.hist) for b in blobs_all[sl]}
            if len(lens) == 1 and next(iter(lens)) > 0:
                hist = np.array([b.hist for b in blobs_all[sl]], dtype=np.float64)
                hist_sqrt = np.sqrt(np.clip(hist, 0.0, None))
        mono_range = mono_sigma = None
        m = (mono or {}).get(sid)
        if m is not None:
            sigma_elev, base, max_range, image_h = m
            cut = tab[sl, 4] >= image_h - 2.0  # a box cut by the lower border does not show the feet
            mono_range, mono_sigma = mono_ranges(np.where(cut, np.nan, bottom), pose.z_m, sigma_elev, base, max_range)
        out[sid] = ViewBlobs(
            sensor_id=sid,
            origin_xy=pose.origin,
            z_m=pose.z_m,
            sigma_rad=sigma,
            bearing_rad=bearing_world[sl],
            width_rad=tab[sl, 1],
            top_elev_rad=tab[sl, 2],
            hist=hist,
            local_id=local_id[sl],
            hist_sqrt=hist_sqrt,
            bottom_elev_rad=bottom,
            fov=(fovs or {}).get(sid),
            mono_range_m=mono_range,
            mono_sigma_m=mono_sigma,
            top_cut=top_cut[sl],
        )
    return out


def _not_bodies(
    entries: list[tuple[str, list[AlignedBlob], PoseEstimate]],
    tab: FloatArray,
    *,
    view_of: npt.NDArray[np.int64],
    sigmas: list[float],
    bodies: dict[str, float] | None,
    poses: dict[str, PoseEstimate],
) -> npt.NDArray[np.bool_]:
    """(n,) False for the blobs that are a known robot/tripod body seen by another camera.

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
    vx = np.array([pose.x_m for _, _, pose in entries])[:, None]
    vy = np.array([pose.y_m for _, _, pose in entries])[:, None]
    vz = np.array([pose.z_m for _, _, pose in entries])[:, None]
    yaw = np.array([pose.yaw_rad for _, _, pose in entries])[:, None]
    sig = np.array(sigmas)[:, None]
    ox, oy, oz = bx - vx, by - vy, bz - vz  # (views, bodies)
    dist = np.hypot(ox, oy)
    ok = (dist > radius) & (np.array([sid for sid, _, _ in entries])[:, None] != np.array([o for o, _ in body_list]))
    half = np.arcsin(np.where(ok, radius / np.maximum(dist, 1e-9), 0.0))
    az = np.arctan2(oy, ox) - yaw
    # The body ends at the other camera (on its axis); a person behind it shows a taller top.
    body_top = np.arctan2(oz + BODY_TOP_MARGIN_M, np.maximum(dist, 1e-9))
    v, s = view_of, sig[view_of]
    is_body = (
        ok[v]
        & (np.abs(wrap(tab[:, 0, None] - az[v])) < half[v] + 3 * s)
        & (tab[:, 1, None] < 3.0 * half[v] + 6 * s)
        & (tab[:, 2, None] < body_top[v])
    )
    keep &= ~np.any(is_body, axis=1)
    return keep


def perspective_fovs(infos: Mapping[str, SensorInfo]) -> dict[str, tuple[float, float]]:
    """Horizontal fields of view of the perspective cameras (see :func:`pinhole_fov`).

    A PTZ head's SensorInfo is re-published with its current orientation whenever it moves: without its
    field of view, every person outside it would count as "not seen" by the PTZ camera in the view
    agreement and the ghost veto (with 4 cameras, min_view_agreement 0.8 then refuses 3 of 4).
    """
    out: dict[str, tuple[float, float]] = {}
    for sid, info in infos.items():
        if info.kind in ("pinhole", "ptz") and isinstance(info.model, PinholeModel):
            fov = pinhole_fov(info.model)
            if fov is not None:
                out[sid] = fov
    return out


def mono_cameras(infos: Mapping[str, SensorInfo], mc: MatchSection) -> dict[str, tuple[float, float, float, float]]:
    """Perspective cameras whose feet elevations give floor distances (:mod:`resource_manager.mono`)."""
    if mc.mono_elev_sigma_deg <= 0:
        return {}
    sigma = math.radians(mc.mono_elev_sigma_deg)
    return {
        sid: (sigma, mc.mono_base_sigma_m, mc.max_range_m, float(info.model.height_px))
        for sid, info in infos.items()
        if info.kind in ("pinhole", "ptz") and isinstance(info.model, PinholeModel)
    }


def pinhole_fov(model: PinholeModel, margin_rad: float = 0.05) -> tuple[float, float] | None:
    """(world azimuth of the optical axis, horizontal half field of view) of a perspective camera.

    None when the camera looks nearly straight down (it then sees every azimuth around its foot).
    """
    r, k = model.r, model.k
    axis_x, axis_y, axis_z = r[6], r[7], r[8]  # the camera z axis in the world: third row of R
    if abs(axis_z) > 0.9 or k[0] <= 0:
        return None
    half = math.atan(max(k[2], model.width_px - k[2]) / k[0]) / max(math.sqrt(axis_x**2 + axis_y**2), 0.3)
    return math.atan2(axis_y, axis_x), min(half + margin_rad, math.pi)


def wrap(a: FloatArray) -> FloatArray:
    return np.asarray((a + math.pi) % TWO_PI - math.pi, dtype=np.float64)


def subset_view(v: ViewBlobs, idx: list[int]) -> ViewBlobs:
    sel = np.asarray(idx, dtype=np.int64)
    return ViewBlobs(
        sensor_id=v.sensor_id,
        origin_xy=v.origin_xy,
        z_m=v.z_m,
        sigma_rad=v.sigma_rad,
        bearing_rad=v.bearing_rad[sel],
        width_rad=v.width_rad[sel],
        top_elev_rad=v.top_elev_rad[sel],
        hist=None if v.hist is None else v.hist[sel],
        local_id=v.local_id[sel],
        hist_sqrt=None if v.hist_sqrt is None else v.hist_sqrt[sel],
        bottom_elev_rad=None if v.bottom_elev_rad is None else v.bottom_elev_rad[sel],
        fov=v.fov,
        mono_range_m=None if v.mono_range_m is None else v.mono_range_m[sel],
        mono_sigma_m=None if v.mono_sigma_m is None else v.mono_sigma_m[sel],
        top_cut=None if v.top_cut is None else v.top_cut[sel],
    )


@dataclass(frozen=True, slots=True)
class AllBlobs:
    """Every blob of every view in flat arrays, to ask "how many cameras see something toward (x, y)?" at once."""

    origin: FloatArray
    """(n, 2) camera position of each blob."""
    bearing: FloatArray
    half_width: FloatArray
    sigma_gate: FloatArray
    view: npt.NDArray[np.int64]
    """(n,) index of the blob's view."""
    view_origin: FloatArray
    """(v, 2) every view's position (views without blobs included)."""
    view_fov: FloatArray
    """(v, 2) axis azimuth and half field of view (half = pi: panoramic)."""
    view_blank: npt.NDArray[np.bool_] | None = None
    """(v,) views that just went blank (no blob this tick, some the tick before): a sudden light change or a
    node restarting blanks every camera for a frame; people leaving leave it blank for longer."""
    mono_range: FloatArray | None = None
    """(n,) feet floor distance of each blob (NaN: unknown)."""
    mono_tol: FloatArray | None = None
    """(n,) ``mono_k`` sigmas of it: a blob whose feet stand beyond the position by more is someone behind it,
    not the person there nor an occluder in front; nearer by more, someone in front."""
    mono_near: FloatArray | None = None
    """(n,) ``mono_range - mono_tol``, -inf where unknown (precomputed: :meth:`agreement` runs per candidate)."""
    mono_far: FloatArray | None = None
    """(n,) ``mono_range + mono_tol``, +inf where unknown."""
    panoramic: bool = False
    """Every view sees all azimuths (no field-of-view test needed)."""

    @staticmethod
    def of(
        views: dict[str, ViewBlobs], k_sigma: float, mono_k: float = 3.0, excused: frozenset[str] = frozenset()
    ) -> AllBlobs:
        """``excused``: views whose (empty) frame says nothing this tick (see ``view_blank``)."""
        vs = list(views.values())
        counts = [v.n for v in vs]
        mono_range = mono_tol = None
        if any(v.mono_range_m is not None for v in vs):
            known = [v.mono_range_m is not None and v.mono_sigma_m is not None for v in vs]
            mono_range = np.concatenate(
                [v.mono_range_m if ok else np.full(v.n, np.nan) for v, ok in zip(vs, known, strict=True)]
            )
            mono_tol = mono_k * np.concatenate(
                [v.mono_sigma_m if ok else np.full(v.n, np.nan) for v, ok in zip(vs, known, strict=True)]
            )
        mono_near = mono_far = None
        if mono_range is not None and mono_tol is not None:
            with np.errstate(invalid="ignore"):
                near, far = mono_range - mono_tol, mono_range + mono_tol
            mono_near = np.where(np.isnan(near), -np.inf, near)
            mono_far = np.where(np.isnan(far), np.inf, far)
        idx = np.repeat(np.arange(len(vs)), counts).astype(np.int64)
        vo = np.array([v.origin_xy for v in vs]).reshape(-1, 2)
        return AllBlobs(
            origin=vo[idx] if idx.size else np.zeros((0, 2)),
            bearing=np.concatenate([v.bearing_rad for v in vs]) if vs else np.zeros(0),
            half_width=0.5 * np.concatenate([v.width_rad for v in vs]) if vs else np.zeros(0),
            sigma_gate=np.repeat([k_sigma * v.sigma_rad for v in vs], counts) if vs else np.zeros(0),
            view=idx,
            view_origin=vo,
            view_fov=np.array([v.fov if v.fov is not None else (0.0, math.pi) for v in vs]).reshape(-1, 2),
            view_blank=np.array([v.n == 0 and v.sensor_id in excused for v in vs], dtype=bool),
            mono_range=mono_range,
            mono_tol=mono_tol,
            mono_near=mono_near,
            mono_far=mono_far,
            panoramic=all(v.fov is None or v.fov[1] >= math.pi for v in vs),
        )

    def agreement(self, xy: FloatArray, max_range_m: float, *, occluders: bool = True) -> tuple[int, int]:
        """(views with a blob toward ``xy``, views within range of ``xy``).

        With ``occluders`` a blob in front of ``xy`` (feet nearer) counts: the person may be hidden behind it.
        Without, a blob with known feet counts only when they stand at ``xy``: is the person *there*?
        """
        # Per view (a handful) first; a blob's distance and predicted bearing are its view's.
        dx = xy[0] - self.view_origin[:, 0]
        dy = xy[1] - self.view_origin[:, 1]
        d_view = np.hypot(dx, dy)
        in_range = (d_view > 0.3) & (d_view <= max_range_m)
        az = np.arctan2(dy, dx)
        if not self.panoramic:  # |wrap(.)| <= pi always holds for a panoramic view
            in_range &= np.abs(wrap(az - self.view_fov[:, 0])) <= self.view_fov[:, 1]  # in its field of view
        if self.view_blank is not None:
            # A view that just went blank is no evidence about xy yet: a blank frame (light change, node
            # restart) must not end or veto every track at once; blank on the next tick too, it counts.
            in_range &= ~self.view_blank
        total = int(np.count_nonzero(in_range))
        if total == 0 or self.bearing.size == 0:
            return 0, total
        dist = np.maximum(d_view, 0.3)[self.view]
        pred = az[self.view]
        ok = np.abs(wrap(self.bearing - pred)) - self.half_width < self.sigma_gate + 0.25 / dist
        if self.mono_near is not None and self.mono_far is not None:
            ok &= ~(self.mono_near > dist)  # unknown feet (-inf, +inf) agree
            if not occluders:
                ok &= ~(self.mono_far < dist)
        elif self.mono_range is not None and self.mono_tol is not None:
            with np.errstate(invalid="ignore"):  # NaN compares False: unknown feet agree
                ok &= ~(self.mono_range - self.mono_tol > dist)
                if not occluders:
                    ok &= ~(self.mono_range + self.mono_tol < dist)
        seen = np.zeros(self.view_origin.shape[0], dtype=bool)
        seen[self.view[ok]] = True
        return int(np.count_nonzero(seen & in_range)), total
