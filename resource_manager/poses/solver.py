"""Camera poses: surveyed ones from config/SensorInfo, mobile ones by mutual calibration.

A pose is known when and only when it is: a surveyed pose (a ``[[pose]]``
override in the manager config, or the pose a sensor reports with
``pose_source = "surveyed"``), or a pose solved this instant by mutual
calibration from sightings and chained from cameras whose pose is known.
Nothing is guessed: a robot that no known camera sees, and that does not see
two known bodies itself, has no pose and its blobs are not used.

Mutual calibration (paper, "Dynamic Mutual Calibration", Eq. 3): camera o sees
robot t's cylinder between two occluding rays at angle α; the baseline is
B = R / sin(α/2) and the direction of t is the mean of the two boundary
bearings. Chaining rules, repeated until nothing changes:

1. *Position by range and bearing*: a camera o with a known pose that sights t
   puts t at p_o + B·(cos, sin)(yaw_o + β_ot); B is averaged with t's own
   measurement of the same baseline when t sights o too (both robots' views).
2. *Orientation from t's own sightings*: once t's position is known, every body
   k of known position that t sights gives yaw_t = atan2(p_k - p_t) - β_tk
   (circular mean over k).
3. *Resection*: t sighting two bodies of known position gives both its yaw (the
   angle between the world and sensor-frame vectors k1->k2) and its position.

Raw poses are smoothed over time with an alpha-beta filter (time constant
``smoothing_s``), and carry the error model's uncertainty: σ_B ≈ B²σ_α/(2R)
(docs/geometry.md §2.1), divided by √2 when both views are averaged.

A raw pose far from the smoothed one (beyond ``jump_m``, or ``outlier_sigmas``)
is refused; the filter restarts there only when ``outlier_run`` refused poses in
a row agree with each other: a robot that really moved gives the same new pose
tick after tick, sightings forged under its id (or a band half hidden) give
poses that agree with nothing. While such poses keep coming the pose is held,
not lost (``timeout_s`` counts from the last raw pose of any kind), so when they
stop the real sightings carry on where they left off.

No single witness moves a camera. Every sighting comes under its sender's own
key, so a stolen camera can lie only in its own sightings; what it says must
agree with the rest:

* the witnesses of a robot's position (each camera that sights it) are checked
  against each other, and one that disagrees is refused
  (:mod:`resource_manager.poses.witness`);
* a camera whose node reports no motion (``Features.state`` is not ``moving``;
  a static camera always) for ``settle_s`` has its pose *fixed* at the mean of
  its poses over that time. From then on sightings only check it: a raw pose off
  it is refused, and nothing restarts the filter elsewhere, however many
  sightings agree on the new place (a stolen camera sends as many as it likes).
  Only the camera's own node reporting motion releases it: then it follows its
  raw poses, at most ``max_speed_mps`` beyond its noise, and settles again when
  the robot stops;
* every refused sighting is counted per sender (:meth:`PoseSolver.take_refused`:
  ``ManagerStatus.refused``, reason ``sighting``). A surveyed pose never moves
  from sightings: it is never solved for.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Collection, Mapping
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from common.angles import wrap_angle
from common.arrays import FloatArray
from common.geometry import baseline_from_alpha, sighting_bearing
from common.schema import SensorInfo
from resource_manager.config import ManagerSection, MutualSection, default_of
from resource_manager.ingest.align import AlignedSighting
from resource_manager.poses.witness import Estimate, Reference, blame, combine, consistent

__all__ = ["MutualParams", "PoseEstimate", "PoseSolver", "RawPose"]

TRUSTED_POSES = 3
"""A calibrated pose is trusted (a reference for the witnesses, refusing raw poses far off it, fixable as the mean
of those taken since the camera stopped) once this many raw poses made it: fewer, and one bad start would stick."""
SAME_POINT_M = 1e-6
"""Two positions closer than this (m) are one point: no direction between them."""
RESECTION_TARGETS = 2
"""A camera placed from its own sightings alone needs two sighted cameras of known pose (a resection)."""

logger = logging.getLogger(__name__)


@dataclass(frozen=True, slots=True)
class MutualParams:
    """``[mutual]`` in the solver's units (rad), with the solver's own knobs; the config's are documented, and
    defaulted, in :class:`resource_manager.config.MutualSection`."""

    enabled: bool = default_of(MutualSection, "enabled")
    smoothing_s: float = default_of(MutualSection, "smoothing_s")
    timeout_s: float = default_of(MutualSection, "timeout_s")
    jump_m: float = default_of(MutualSection, "jump_m")
    hold: bool = True
    """Keep a pose (predicted) between instants where it could be solved, until ``timeout_s``."""
    outlier_sigmas: float = 3.0
    """A raw pose further than this many sigmas (plus 5 cm, 0.5 deg) from the smoothed one is refused; 0: off."""
    outlier_run: int = 5
    """...unless this many in a row were, and agree with each other (then it is followed: the robot moved)."""
    boundary_sigma_rad: float = math.radians(default_of(MutualSection, "boundary_sigma_deg"))
    default_bearing_sigma_rad: float = math.radians(default_of(ManagerSection, "default_bearing_sigma_deg"))
    default_height_m: float = default_of(MutualSection, "default_height_m")
    settle_s: float = default_of(MutualSection, "settle_s")
    max_speed_mps: float = default_of(MutualSection, "max_speed_mps")


@dataclass(frozen=True, slots=True)
class PoseEstimate:
    """A sensor's pose at the fusion instant and its uncertainty."""

    sensor_id: str
    x_m: float
    y_m: float
    z_m: float
    yaw_rad: float
    source: Literal["surveyed", "mutual"]
    sigma_xy_m: float = 0.0
    sigma_yaw_rad: float = 0.0

    @property
    def origin(self) -> FloatArray:
        return np.array([self.x_m, self.y_m])


@dataclass(frozen=True, slots=True)
class RawPose:
    """One instant's mutual-calibration solution before smoothing."""

    x_m: float
    y_m: float
    yaw_rad: float
    sigma_xy_m: float
    sigma_yaw_rad: float


@dataclass(slots=True)
class _Filter:
    x: float
    y: float
    yaw: float
    vx: float = 0.0
    vy: float = 0.0
    vyaw: float = 0.0
    t_ns: int = 0
    n: int = 1
    sigma_xy: float = 0.0
    sigma_yaw: float = 0.0
    outliers: int = 0
    """Consecutive raw poses refused as outliers."""
    refused: list[RawPose] = field(default_factory=list)
    """The latest of them (at most ``outlier_run``): a restart needs them to agree."""
    contested_ns: int = 0
    """When the last refused raw pose came: the pose is held, not timed out, while they keep coming."""
    still_ns: int = 0
    """Since when the camera's node reports no motion (0: it moves now)."""
    moved_ns: int = 0
    """When its node last reported motion (0: never since the filter started)."""
    fixed: bool = False
    """Settled: the pose is fixed; sightings only check it."""
    settle: list[RawPose] = field(default_factory=list)
    """The raw poses taken since the camera stopped: their mean is the fixed pose."""


@dataclass(slots=True)
class _Obs:
    bearing_rad: float
    baseline_m: float
    sigma_b_m: float


@dataclass(slots=True)
class PoseSolver:
    """Keeps surveyed poses and solves mobile ones each tick."""

    params: MutualParams = field(default_factory=MutualParams)
    overrides: dict[str, PoseEstimate] = field(default_factory=dict)
    infos: Mapping[str, SensorInfo] = field(default_factory=dict)
    """Every sensor's SensorInfo, read from the manager's sensor registry (:mod:`resource_manager.sensors`)."""
    filters: dict[str, _Filter] = field(default_factory=dict)
    refused: dict[str, int] = field(default_factory=dict)
    """Sender id -> its sightings refused since :meth:`take_refused` (one count per sender, target and instant)."""
    _estimates: dict[str, list[Estimate]] = field(default_factory=dict)
    """This instant's witnesses of each target's position (those kept)."""

    def take_refused(self) -> dict[str, int]:
        """Refused sightings per sender since the last call."""
        out, self.refused = self.refused, {}
        return out

    def _refuse_senders(self, senders: Collection[str]) -> None:
        for sid in senders:
            if sid in self.refused or len(self.refused) < 4 * max(16, len(self.infos)):
                self.refused[sid] = self.refused.get(sid, 0) + 1

    def forget(self, sensor_id: str) -> None:
        """The sensor left: its calibrated pose goes."""
        self.filters.pop(sensor_id, None)

    def bearing_sigma(self, sensor_id: str) -> float:
        info = self.infos.get(sensor_id)
        return (
            info.bearing_sigma_rad
            if info is not None and info.bearing_sigma_rad > 0
            else self.params.default_bearing_sigma_rad
        )

    def surveyed(self) -> dict[str, PoseEstimate]:
        """Poses known without calibration: overrides first, then surveyed SensorInfo poses."""
        out: dict[str, PoseEstimate] = {}
        for sid, info in self.infos.items():
            if info.pose is not None and info.pose_source == "surveyed":
                p = info.pose
                out[sid] = PoseEstimate(sid, p.x_m, p.y_m, p.z_m, p.yaw_rad, "surveyed")
        out.update(self.overrides)
        return out

    def _height(self, sensor_id: str) -> float | None:
        """The optical centre's height: from SensorInfo (a mobile node may report z only), else the default."""
        info = self.infos.get(sensor_id)
        if info is None:
            return None
        if info.pose is not None and info.pose.z_m > 0:
            return info.pose.z_m
        return self.params.default_height_m

    def _observations(
        self, sightings: dict[str, list[AlignedSighting]], known: dict[str, PoseEstimate]
    ) -> dict[tuple[str, str], _Obs]:
        obs: dict[tuple[str, str], _Obs] = {}
        for observer, items in sightings.items():
            sigma_b = self.params.boundary_sigma_rad or self.bearing_sigma(observer)
            for s in items:
                if not s.target_id or s.target_id == observer or s.body_radius_m <= 0:
                    continue
                if observer in known and s.target_id in known:
                    continue  # both poses known: this sighting can locate nobody
                alpha = abs(float(wrap_angle(s.left_rad - s.right_rad)))
                if not 0.0 < alpha < math.pi:
                    continue
                b = float(baseline_from_alpha(alpha, s.body_radius_m))
                # σ_B ≈ B²σ_α/(2R), σ_α = √2 σ_boundary (two boundaries).
                sigma = b * b * math.sqrt(2.0) * sigma_b / (2.0 * s.body_radius_m)
                obs[(observer, s.target_id)] = _Obs(float(sighting_bearing(s.left_rad, s.right_rad)), b, sigma)
        return obs

    def solve_raw(
        self, sightings: dict[str, list[AlignedSighting]], known: dict[str, PoseEstimate]
    ) -> dict[str, RawPose]:
        """One instant's mutual calibration, chained from ``known`` poses (no smoothing)."""
        obs = self._observations(sightings, known)
        full: dict[str, tuple[float, float, float, float, float]] = {
            k: (p.x_m, p.y_m, p.yaw_rad, p.sigma_xy_m, p.sigma_yaw_rad) for k, p in known.items()
        }
        positions: dict[str, tuple[float, float, float]] = {k: (v[0], v[1], v[3]) for k, v in full.items()}
        solved: dict[str, RawPose] = {}
        candidates = {t for (_, t) in obs} | {o for (o, _) in obs}
        changed = True
        while changed:
            changed = False
            for t in sorted(candidates - set(full)):
                if t not in positions:
                    pos = self._position_from_observers(t, obs, full)
                    if pos is not None:
                        positions[t] = pos
                        changed = True
                if t in positions:
                    yaw = self._yaw_from_own(t, obs, positions)
                    if yaw is not None:
                        x, y, sxy = positions[t]
                        full[t] = (x, y, yaw[0], sxy, yaw[1])
                        solved[t] = RawPose(x, y, yaw[0], sxy, yaw[1])
                        changed = True
                        continue
                res = self._resection(t, obs, positions)
                if res is not None:
                    full[t] = (res.x_m, res.y_m, res.yaw_rad, res.sigma_xy_m, res.sigma_yaw_rad)
                    positions[t] = (res.x_m, res.y_m, res.sigma_xy_m)
                    solved[t] = res
                    changed = True
        return solved

    def _position_from_observers(
        self, t: str, obs: dict[tuple[str, str], _Obs], full: dict[str, tuple[float, float, float, float, float]]
    ) -> tuple[float, float, float] | None:
        found: list[Estimate] = []
        for (o, tt), ob in obs.items():
            if tt != t or o not in full:
                continue
            ox, oy, oyaw, osxy, osyaw = full[o]
            b, sb = ob.baseline_m, ob.sigma_b_m
            back = obs.get((t, o))
            if back is not None:  # both robots' views of the same baseline
                b = 0.5 * (b + back.baseline_m)
                sb = 0.5 * math.hypot(sb, back.sigma_b_m)
            ang = oyaw + ob.bearing_rad
            s_perp = b * math.hypot(self.bearing_sigma(o), osyaw)
            s = math.sqrt(sb * sb + s_perp * s_perp + osxy * osxy)
            found.append(Estimate(o, ox + b * math.cos(ang), oy + b * math.sin(ang), s))
        if not found:
            return None
        # Witnesses that disagree with the rest are refused (and counted), worst first.
        kept, refused = consistent(found, self._k(), self._reference(t))
        self._refuse_senders(refused)
        self._estimates[t] = kept
        return combine(kept)

    def _k(self) -> float:
        return max(self.params.outlier_sigmas, 3.0)

    def _reference(self, t: str) -> Reference | None:
        """Where ``t`` was held before this instant (its filter), if anywhere."""
        f = self.filters.get(t)
        return None if f is None or f.n < TRUSTED_POSES else Reference(f.x, f.y, f.sigma_xy)

    def _yaw_from_own(
        self, t: str, obs: dict[tuple[str, str], _Obs], positions: dict[str, tuple[float, float, float]]
    ) -> tuple[float, float] | None:
        tx, ty, tsxy = positions[t]
        sins, coss, sig = 0.0, 0.0, []
        for (o, k), ob in obs.items():
            if o != t or k not in positions:
                continue
            kx, ky, ksxy = positions[k]
            dist = math.hypot(kx - tx, ky - ty)
            if dist < SAME_POINT_M:
                continue
            yaw = math.atan2(ky - ty, kx - tx) - ob.bearing_rad
            s = math.hypot(self.bearing_sigma(t), math.hypot(tsxy, ksxy) / dist)
            w = 1.0 / max(s * s, 1e-12)
            sins += w * math.sin(yaw)
            coss += w * math.cos(yaw)
            sig.append(w)
        if not sig:
            return None
        return float(wrap_angle(math.atan2(sins, coss))), 1.0 / math.sqrt(sum(sig))

    def _resection(
        self, t: str, obs: dict[tuple[str, str], _Obs], positions: dict[str, tuple[float, float, float]]
    ) -> RawPose | None:
        seen = [(k, ob) for (o, k), ob in obs.items() if o == t and k in positions and k != t]
        if len(seen) < RESECTION_TARGETS:
            return None
        (k1, o1), (k2, o2) = sorted(seen, key=lambda kv: kv[1].sigma_b_m)[:2]
        p1, p2 = positions[k1], positions[k2]
        v_sensor = (
            o2.baseline_m * math.cos(o2.bearing_rad) - o1.baseline_m * math.cos(o1.bearing_rad),
            o2.baseline_m * math.sin(o2.bearing_rad) - o1.baseline_m * math.sin(o1.bearing_rad),
        )
        if math.hypot(*v_sensor) < SAME_POINT_M:
            return None
        yaw = float(wrap_angle(math.atan2(p2[1] - p1[1], p2[0] - p1[0]) - math.atan2(v_sensor[1], v_sensor[0])))
        xs = [p[0] - ob.baseline_m * math.cos(yaw + ob.bearing_rad) for p, ob in ((p1, o1), (p2, o2))]
        ys = [p[1] - ob.baseline_m * math.sin(yaw + ob.bearing_rad) for p, ob in ((p1, o1), (p2, o2))]
        sxy = math.hypot(o1.sigma_b_m, o2.sigma_b_m) / 2.0 + max(p1[2], p2[2])
        syaw = math.hypot(o1.sigma_b_m, o2.sigma_b_m) / max(math.hypot(p2[0] - p1[0], p2[1] - p1[1]), 1e-6)
        return RawPose(sum(xs) / 2.0, sum(ys) / 2.0, yaw, sxy, math.hypot(syaw, self.bearing_sigma(t)))

    def solve(
        self, sightings: dict[str, list[AlignedSighting]], t_ns: int, moving: Collection[str] = ()
    ) -> dict[str, PoseEstimate]:
        """Every pose known at ``t_ns``: surveyed ones plus smoothed mutual-calibration ones.

        Args:
            sightings: each sender's sightings aligned to ``t_ns``.
            moving: the cameras whose own node reports motion at ``t_ns`` (``Features.state == "moving"``): only
                these may move (a static camera never does).
        """
        known = self.surveyed()
        if not self.params.enabled:
            return known
        self._estimates = {}
        raw = self.solve_raw(sightings, known)
        out = dict(known)
        timeout_ns = int(self.params.timeout_s * 1e9)
        for sid in moving:
            f0, info = self.filters.get(sid), self.infos.get(sid)
            if f0 is not None and info is not None and info.mobile and sid not in raw:
                # Its node reports motion and nothing places it now: released, it times out like any moving pose.
                f0.fixed, f0.still_ns, f0.moved_ns, f0.settle = False, 0, t_ns, []
        for sid, rp in raw.items():
            info = self.infos.get(sid)
            self._smooth(sid, rp, t_ns, moving=sid in moving and info is not None and info.mobile)
        for sid, f in list(self.filters.items()):
            if sid in known:
                del self.filters[sid]
                continue
            # A fixed pose is kept while the camera's node reports no motion, sightings or not (a person in front
            # of the bands, a loaded host's late frames): the camera has not moved. It goes when its node reports
            # motion, or leaves (liveliness: forget()).
            if not f.fixed and t_ns - max(f.t_ns, f.contested_ns) > timeout_ns:
                logger.info("pose of %s lost: no sighting for %.1f s", sid, (t_ns - f.t_ns) / 1e9)
                del self.filters[sid]
                continue
            z = self._height(sid)
            if z is None:
                continue
            if sid in raw:
                out[sid] = PoseEstimate(sid, f.x, f.y, z, float(wrap_angle(f.yaw)), "mutual", f.sigma_xy, f.sigma_yaw)
            elif self.params.hold:
                # Not solved at this instant (a person walks between the robots): the smoothed pose, predicted
                # forward, until the timeout. Dropping the camera for those ticks loses every person it supports.
                dt = (t_ns - f.t_ns) / 1e9
                x, y, yaw = f.x + f.vx * dt, f.y + f.vy * dt, f.yaw + f.vyaw * dt
                grow = 1.0 if f.fixed else 1.0 + dt / self.params.smoothing_s
                out[sid] = PoseEstimate(
                    sid, x, y, z, float(wrap_angle(yaw)), "mutual", f.sigma_xy * grow, f.sigma_yaw * grow
                )
        return out

    def _restart(self, sid: str, rp: RawPose, t_ns: int) -> None:
        self.filters[sid] = _Filter(
            rp.x_m, rp.y_m, rp.yaw_rad, t_ns=t_ns, sigma_xy=rp.sigma_xy_m, sigma_yaw=rp.sigma_yaw_rad
        )

    def _agree(self, poses: list[RawPose]) -> bool:
        """Whether refused raw poses agree with each other (the same new place), within their sigmas."""
        k = max(self.params.outlier_sigmas, 3.0)
        mx = sum(p.x_m for p in poses) / len(poses)
        my = sum(p.y_m for p in poses) / len(poses)
        myaw = math.atan2(sum(math.sin(p.yaw_rad) for p in poses), sum(math.cos(p.yaw_rad) for p in poses))
        for p in poses:
            if math.hypot(p.x_m - mx, p.y_m - my) > k * p.sigma_xy_m + 0.05:
                return False
            if abs(float(wrap_angle(p.yaw_rad - myaw))) > k * p.sigma_yaw_rad + math.radians(0.5):
                return False
        return True

    def _refuse(self, sid: str, f: _Filter, rp: RawPose, t_ns: int) -> None:
        """A raw pose off the smoothed one: held back, its witnesses counted; ``outlier_run`` of them that agree
        restart the filter, but only while the camera's own node reports motion (it may have been driven there)."""
        f.outliers += 1
        f.contested_ns = t_ns
        self._refuse_senders(blame(self._estimates.get(sid, []), sid, Reference(f.x, f.y, f.sigma_xy), self._k()))
        f.refused = [*f.refused[-(self.params.outlier_run - 1) :], rp] if self.params.outlier_run > 1 else [rp]
        if not f.fixed and len(f.refused) >= self.params.outlier_run and self._agree(f.refused):
            # A camera that moved can be no further than its top speed took it since its last taken pose.
            reach_m = self.params.jump_m + self.params.max_speed_mps * (t_ns - f.t_ns) / 1e9
            if f.moved_ns and math.hypot(rp.x_m - f.x, rp.y_m - f.y) > reach_m:
                return
            self._restart(sid, rp, t_ns)
            g = self.filters[sid]
            g.still_ns, g.moved_ns, g.settle = f.still_ns and t_ns, f.moved_ns, [rp]

    def _check_fixed(self, sid: str, f: _Filter, rp: RawPose, t_ns: int) -> None:
        """A settled camera: a raw pose that agrees with its fixed pose keeps it alive; any other is refused."""
        k = self._k()
        tol_xy = k * math.hypot(rp.sigma_xy_m, f.sigma_xy) + 0.05
        tol_yaw = k * math.hypot(rp.sigma_yaw_rad, f.sigma_yaw) + math.radians(0.5)
        if math.hypot(rp.x_m - f.x, rp.y_m - f.y) > tol_xy or abs(float(wrap_angle(rp.yaw_rad - f.yaw))) > tol_yaw:
            self._refuse(sid, f, rp, t_ns)
            return
        f.outliers = 0
        f.refused = []
        f.t_ns = t_ns

    def _settle(self, f: _Filter, t_ns: int) -> None:
        """Fix the pose of a camera still for ``settle_s``: the mean of its raw poses since it stopped."""
        if (
            f.fixed
            or f.still_ns == 0
            or t_ns - f.still_ns < int(self.params.settle_s * 1e9)
            or len(f.settle) < TRUSTED_POSES
        ):
            return
        f.x = sum(p.x_m for p in f.settle) / len(f.settle)
        f.y = sum(p.y_m for p in f.settle) / len(f.settle)
        f.yaw = math.atan2(sum(math.sin(p.yaw_rad) for p in f.settle), sum(math.cos(p.yaw_rad) for p in f.settle))
        f.vx = f.vy = f.vyaw = 0.0
        f.fixed = True
        f.settle = []

    def _smooth(self, sid: str, rp: RawPose, t_ns: int, *, moving: bool = False) -> None:
        f = self.filters.get(sid)
        timeout_ns = int(self.params.timeout_s * 1e9)
        if f is None or t_ns - max(f.t_ns, f.contested_ns) > timeout_ns:
            self._restart(sid, rp, t_ns)
            f = self.filters[sid]
            f.settle = [rp]
            f.still_ns, f.moved_ns = (0, t_ns) if moving else (t_ns, 0)
            return
        if t_ns <= f.t_ns:
            return
        if moving:
            f.fixed, f.still_ns, f.moved_ns, f.settle = False, 0, t_ns, []
        elif f.still_ns == 0:
            f.still_ns = t_ns
        if f.fixed:
            self._check_fixed(sid, f, rp, t_ns)
            return
        if self._follow(sid, f, rp, t_ns) and f.still_ns:
            f.settle.append(rp)
            self._settle(f, t_ns)

    def _follow(self, sid: str, f: _Filter, rp: RawPose, t_ns: int) -> bool:
        """Alpha-beta smoothing of a released (or not yet settled) pose; False when ``rp`` was refused."""
        dt = (t_ns - f.t_ns) / 1e9
        # How far the camera may have gone since its last taken pose: only while its node reported motion.
        reach = self.params.max_speed_mps * dt if f.moved_ns else 0.0
        if math.hypot(rp.x_m - f.x, rp.y_m - f.y) > self.params.jump_m + reach:
            if f.n >= TRUSTED_POSES:
                self._refuse(sid, f, rp, t_ns)
                return False
            # A young filter follows: it may have started from a bad pose.
            self._restart(sid, rp, t_ns)
            g = self.filters[sid]
            g.still_ns, g.moved_ns, g.settle = f.still_ns, f.moved_ns, [rp]
            return False
        a = 1.0 - math.exp(-dt / self.params.smoothing_s)
        bgain = a * a / (2.0 - a)
        px, py, pyaw = f.x + f.vx * dt, f.y + f.vy * dt, f.yaw + f.vyaw * dt
        rx, ry, ryaw = rp.x_m - px, rp.y_m - py, float(wrap_angle(rp.yaw_rad - pyaw))
        k = self.params.outlier_sigmas
        if k > 0 and f.n >= TRUSTED_POSES:
            # A raw pose far off the smoothed one (a person in front of the other robot's body shifts its
            # boundaries) is refused; when such poses persist, the robot really moved: start again there.
            tol_xy = k * math.hypot(rp.sigma_xy_m, f.sigma_xy) + 0.05
            tol_yaw = k * math.hypot(rp.sigma_yaw_rad, f.sigma_yaw) + math.radians(0.5)
            if math.hypot(rx, ry) > tol_xy or abs(ryaw) > tol_yaw:
                self._refuse(sid, f, rp, t_ns)
                return False
        f.outliers = 0
        f.refused = []
        f.x, f.y, f.yaw = px + a * rx, py + a * ry, float(wrap_angle(pyaw + a * ryaw))
        f.vx += bgain * rx / dt
        f.vy += bgain * ry / dt
        f.vyaw += bgain * ryaw / dt
        f.t_ns = t_ns
        f.n += 1
        shrink = max(math.sqrt(a / (2.0 - a)), 1.0 / math.sqrt(f.n))
        f.sigma_xy = rp.sigma_xy_m * shrink
        f.sigma_yaw = rp.sigma_yaw_rad * shrink
        return True
