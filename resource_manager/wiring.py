"""The manager's stages built from its config (``[manager]``, ``[mutual]``, ``[[pose]]``, ``[tracker]``,
``[planner]``, ``[ptz]``): config units (s, deg) turned into each stage's own (ns, rad)."""

from __future__ import annotations

import math
from collections.abc import Callable

from common.geometry import wrap_angle
from resource_manager.config import ManagerConfig
from resource_manager.ingest.align import AlignParams
from resource_manager.plan.planner import PlannerParams, ViewPlanner
from resource_manager.poses.solver import MutualParams, PoseEstimate, PoseSolver
from resource_manager.serve.ptz import PtzAllocator, PtzParams
from resource_manager.settling import SettleParams, ViewTrust
from resource_manager.track import Tracker, TrackParams

__all__ = ["align_params", "pose_solver", "ptz_allocator", "tracker", "view_planner", "view_trust"]


def align_params(config: ManagerConfig) -> AlignParams:
    m = config.manager
    return AlignParams(
        max_extrapolation_ns=int(m.max_extrapolation_ms * 1e6),
        stale_ns=int(m.stale_ms * 1e6),
        max_gap_ns=int(m.max_gap_ms * 1e6),
    )


def pose_solver(config: ManagerConfig) -> PoseSolver:
    """Mutual calibration with the ``[[pose]]`` overrides as surveyed poses."""
    mu = config.mutual
    solver = PoseSolver(
        MutualParams(
            enabled=mu.enabled,
            smoothing_s=mu.smoothing_s,
            timeout_s=mu.timeout_s,
            jump_m=mu.jump_m,
            boundary_sigma_rad=math.radians(mu.boundary_sigma_deg),
            default_bearing_sigma_rad=config.default_bearing_sigma_rad,
            default_height_m=mu.default_height_m,
        )
    )
    for p in config.pose:
        solver.overrides[p.id] = PoseEstimate(
            p.id, p.x_m, p.y_m, p.z_m, float(wrap_angle(math.radians(p.yaw_deg))), "surveyed"
        )
    return solver


def tracker(config: ManagerConfig, new_id: Callable[[], str]) -> Tracker:
    t = config.tracker
    return Tracker(
        TrackParams(
            accel_sigma_mps2=t.accel_sigma_mps2,
            gate_chi2=t.gate_chi2,
            gate_min_m=t.gate_min_m,
            min_meas_sigma_m=t.min_meas_sigma_m,
            birth_hits=t.birth_hits,
            birth_window=t.birth_window,
            max_misses=t.max_misses,
            init_speed_sigma_mps=t.init_speed_sigma_mps,
            height_alpha=t.height_alpha,
            max_speed_mps=t.max_speed_mps,
            max_gate_m=t.max_gate_m,
            coast_damping_s=t.coast_damping_s,
            relink_s=t.relink_s,
            relink_m=t.relink_m,
        ),
        new_id,
    )


def view_planner(config: ManagerConfig) -> ViewPlanner:
    pl = config.planner
    room = (pl.room[0], pl.room[1], pl.room[2], pl.room[3]) if len(pl.room) == 4 else None
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


def ptz_allocator(config: ManagerConfig) -> PtzAllocator:
    pz = config.ptz
    return PtzAllocator(
        PtzParams(
            pz.max_range_m,
            pz.aim_height_frac,
            pz.target_width_m,
            math.radians(pz.hfov_deg),
            pz.max_zoom,
            math.radians(pz.min_tilt_deg),
            math.radians(pz.max_tilt_deg),
            pz.lease_s,
        )
    )
