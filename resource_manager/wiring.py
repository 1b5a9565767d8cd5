"""The manager's stages built from its config (``[manager]``, ``[mutual]``, ``[[pose]]``, ``[tracker]``,
``[planner]``, ``[ptz]``, ``[area]``): config units (s, deg) turned into each stage's own (ns, rad); the tracker
reads its ``[tracker]`` table as it is."""

from __future__ import annotations

import math
from collections.abc import Callable

from common.angles import wrap_angle
from common.area import Area, AreaSpec, NearZone
from resource_manager.config import ROOM_FIELDS, ManagerConfig
from resource_manager.ingest.align import AlignParams
from resource_manager.ingest.schedule import ScheduleParams, Scheduler
from resource_manager.plan.planner import PlannerParams, ViewPlanner
from resource_manager.poses.solver import MutualParams, PoseEstimate, PoseSolver
from resource_manager.sensors import SensorRegistry
from resource_manager.serve.ptz import PtzAllocator, PtzParams
from resource_manager.stereo.match import MatchParams, get_matcher
from resource_manager.track.births import BirthParams
from resource_manager.track.model import Scene
from resource_manager.track.tracker import Tracker
from resource_manager.views.build import FeetModel
from resource_manager.views.settling import SettleParams, ViewTrust

__all__ = [
    "ZONE_REACH_BANDS",
    "align_params",
    "area",
    "feet_model",
    "match_params",
    "pose_solver",
    "ptz_allocator",
    "scene",
    "schedule",
    "sensor_registry",
    "tracker",
    "view_planner",
    "view_trust",
]

ZONE_REACH_BANDS = 2.0
"""A zone manager follows people up to this many of its bands (``zone_band_m``) outside its zone."""


def align_params(config: ManagerConfig) -> AlignParams:
    m = config.manager
    return AlignParams(
        max_extrapolation_ns=int(m.max_extrapolation_ms * 1e6),
        stale_ns=int(m.stale_ms * 1e6),
        max_gap_ns=int(m.max_gap_ms * 1e6),
    )


def sensor_registry(config: ManagerConfig) -> SensorRegistry:
    """What the manager knows of each sensor: ``buffer_frames`` frames each, ``clock_step_ms`` a clock step."""
    m = config.manager
    return SensorRegistry(m.buffer_frames, int(m.clock_step_ms * 1e6), _max_wait_ns(config))


def _max_wait_ns(config: ManagerConfig) -> int:
    return int(config.manager.latency_ms * 1e6)


def schedule(config: ManagerConfig, sensors: SensorRegistry) -> Scheduler:
    """When to fuse (``schedule``): the sensors' watermark, a late sensor waited for at most ``latency_ms``, at
    most ``rate_hz``; or ``fixed``: ``latency_ms`` behind the clock at ``rate_hz``."""
    m = config.manager
    params = ScheduleParams(mode=m.schedule, max_wait_ns=_max_wait_ns(config), min_interval_ns=int(1e9 / m.rate_hz))
    return Scheduler(params, sensors.timing)


def pose_solver(config: ManagerConfig, sensors: SensorRegistry) -> PoseSolver:
    """Mutual calibration with the ``[[pose]]`` overrides as surveyed poses."""
    mu = config.mutual
    solver = PoseSolver(
        infos=sensors.infos,
        params=MutualParams(
            enabled=mu.enabled,
            smoothing_s=mu.smoothing_s,
            timeout_s=mu.timeout_s,
            jump_m=mu.jump_m,
            boundary_sigma_rad=math.radians(mu.boundary_sigma_deg),
            default_bearing_sigma_rad=config.default_bearing_sigma_rad,
            default_height_m=mu.default_height_m,
            settle_s=mu.settle_s,
            max_speed_mps=mu.max_speed_mps,
        ),
    )
    for p in config.pose:
        solver.overrides[p.id] = PoseEstimate(
            p.id, p.x_m, p.y_m, p.z_m, float(wrap_angle(math.radians(p.yaw_deg))), "surveyed"
        )
    return solver


def scene(config: ManagerConfig) -> Scene:
    """What the tracker knows of the site: its area, and how far its cameras see anyone (``[match]``).

    A zone manager (``[manager] zone_polygon``) follows people within two bands of its zone only: in the first a
    neighbour publishes them (resource_manager/serve/zones.py), the second leaves the time to start and name a
    track before they reach it. Its cameras see farther; the people there are its neighbours' to follow.
    """
    m = config.manager
    site_area = area(config)
    if m.zone_polygon:
        zone = Area.of(AreaSpec(polygon=m.zone_polygon), "manager.zone_polygon")
        return Scene(
            area=NearZone(zone, ZONE_REACH_BANDS * m.zone_band_m, site_area), max_range_m=config.match.max_range_m
        )
    return Scene(area=site_area, max_range_m=config.match.max_range_m)


def match_params(config: ManagerConfig) -> MatchParams:
    """``[match]`` as Eq. 7's measures."""
    mc = config.match
    return MatchParams(
        max_range_m=mc.max_range_m,
        width_sigma=mc.width_sigma,
        height_sigma=mc.height_sigma,
        use_colour=mc.use_colour,
        floor_sigma_m=mc.floor_sigma_m,
        width_floor=mc.width_floor,
    )


def feet_model(config: ManagerConfig) -> FeetModel | None:
    """How perspective cameras' box bottoms give floor distances (None: ``feet_sigma_deg = 0``)."""
    mc = config.match
    if mc.feet_sigma_deg <= 0:
        return None
    t = config.tracker
    return FeetModel(math.radians(mc.feet_sigma_deg), 0.0, mc.max_range_m, (t.height_prior_m, t.height_sigma_m))


def tracker(config: ManagerConfig, new_id: Callable[[], str]) -> Tracker:
    mc = config.match
    births = BirthParams(
        match=match_params(config),
        threshold=mc.threshold,
        matcher=get_matcher(config.manager.matcher),
        max_pairs=mc.max_birth_pairs,
        width_rel_sigma=mc.width_rel_sigma,
    )
    return Tracker(config.tracker, births, new_id, scene=scene(config), pair_choice=mc.pair_choice)


def area(config: ManagerConfig) -> Area | None:
    """The site's area (``[area]``), validated."""
    return Area.of(config.area) if config.area is not None else None


def view_planner(config: ManagerConfig) -> ViewPlanner:
    pl = config.planner
    site_area = area(config)
    room = (pl.room[0], pl.room[1], pl.room[2], pl.room[3]) if len(pl.room) == len(ROOM_FIELDS) else None
    if room is None and site_area is not None:
        room = site_area.bounds
    return ViewPlanner(
        PlannerParams(
            enabled=pl.enabled,
            period_ns=int(pl.period_s * 1e9),
            room=room,
            margin_m=pl.margin_m,
            min_move_m=pl.min_move_m,
            gain_frac=pl.gain_frac,
            min_gain_m=pl.min_gain_m,
            settle_ns=int(pl.settle_s * 1e9),
            band_z_m=pl.band_z_m,
            elev_margin_rad=math.radians(pl.elev_margin_deg),
            min_band_px=pl.min_band_px,
            keep_m=pl.keep_m,
            found_m=pl.found_m,
            horizon_s=pl.horizon_s,
            speed_mps=pl.speed_mps,
        )
    )


def view_trust(config: ManagerConfig) -> ViewTrust:
    """Which cameras' views count (settling.py)."""
    return ViewTrust(SettleParams(enabled=config.planner.settle_views))


def ptz_allocator(config: ManagerConfig, sensors: SensorRegistry) -> PtzAllocator:
    pz = config.ptz
    return PtzAllocator(
        infos=sensors.infos,
        present=sensors.present,
        params=PtzParams(
            pz.max_range_m,
            pz.aim_height_frac,
            pz.target_width_m,
            math.radians(pz.hfov_deg),
            pz.max_zoom,
            math.radians(pz.min_tilt_deg),
            math.radians(pz.max_tilt_deg),
            pz.lease_s,
            dict(pz.max_priority),
            pz.default_max_priority,
        ),
    )
