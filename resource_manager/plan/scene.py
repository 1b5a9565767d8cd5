"""The view planner's records: its parameters, the cameras, the people and one mobile camera's problem.

Shared by the planner (:mod:`.planner`) and its checks (:mod:`.checks`), which import them from here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from common.arrays import FloatArray
from common.schema import PanoramicModel, SensorInfo
from resource_manager.config import PlannerSection, default_of

__all__ = [
    "PAL_ELEV_MAX_RAD",
    "PAL_ELEV_MIN_RAD",
    "PlanCamera",
    "PlanGoal",
    "PlanTarget",
    "PlannerParams",
    "Scene",
    "plan_camera",
]


PAL_ELEV_MIN_RAD = math.radians(-15.0)
PAL_ELEV_MAX_RAD = math.radians(20.0)
"""The PAL lens' elevation range (paper, Fig. 1; ``common.cameras.design_pal``)."""


@dataclass(frozen=True, slots=True)
class PlannerParams:
    """``[planner]`` in the planner's units (ns, rad), with the planner's own knobs; the config's are defaulted
    in :class:`resource_manager.config.PlannerSection`."""

    enabled: bool = default_of(PlannerSection, "enabled")
    period_ns: int = int(default_of(PlannerSection, "period_s") * 1e9)
    room: tuple[float, float, float, float] | None = None
    margin_m: float = default_of(PlannerSection, "margin_m")
    min_move_m: float = default_of(PlannerSection, "min_move_m")
    gain_frac: float = default_of(PlannerSection, "gain_frac")
    min_gain_m: float = default_of(PlannerSection, "min_gain_m")
    settle_ns: int = int(default_of(PlannerSection, "settle_s") * 1e9)
    band_z_m: float = default_of(PlannerSection, "band_z_m")
    elev_margin_rad: float = math.radians(default_of(PlannerSection, "elev_margin_deg"))
    min_band_px: float = default_of(PlannerSection, "min_band_px")
    keep_m: float = default_of(PlannerSection, "keep_m")
    body_clearance_m: float = 0.15
    """Extra clearance between two bodies (beyond the sum of their radii)."""
    sight_clearance_m: float = 0.35
    """The person must be this far from the line of sight goal - main camera."""
    grid_step_m: float = 0.1
    relearn_ns: int = 4_000_000_000
    """After a robot reaches its goal, its node relearns the background this long (no blobs: see ``driving``)."""
    travel_frac_per_m: float = 0.01
    """Among near-equal goals (the map is flat; Fig. 4 has two symmetric optima) the nearer wins: the
    error is weighed (1 + this x the drive's length) when choosing."""
    speed_mps: float = default_of(PlannerSection, "speed_mps")
    settle_cost_s: float = 1.5
    """After the stop, its node relearns the background and its pose re-converges (settling.py) first."""
    horizon_s: float = default_of(PlannerSection, "horizon_s")
    found_m: float = default_of(PlannerSection, "found_m")
    min_found_gain_s: float = 1.0
    """A move must gain this many found person-seconds more than it loses (everyone found either way: no gain)."""
    persist_s: float = 3.0
    """The target's chance of being found where the robot stands is averaged over about this long
    (exponentially) before it is weighed: someone crossing the line between two cameras soon leaves it."""


@dataclass(frozen=True, slots=True)
class PlanGoal:
    sensor_id: str
    partner_id: str
    track_id: str
    goal_xy: tuple[float, float]
    baseline_m: float
    phi1_rad: float
    predicted_error_m: float
    current_error_m: float


@dataclass(frozen=True, slots=True)
class PlanTarget:
    """What the planner needs of a track."""

    track_id: str
    xy: FloatArray
    predicted_error_m: float
    sensors: tuple[str, ...]
    height_m: float
    """Top of the head above the floor."""


@dataclass(frozen=True, slots=True)
class PlanCamera:
    sensor_id: str
    xy: FloatArray
    radius_m: float
    """Body radius R used by Eq. 3 (the error model's baseline term); 0: no body."""
    sigma_rad: float
    mobile: bool
    z_m: float = 1.1
    """Optical centre height."""
    elev_min_rad: float = PAL_ELEV_MIN_RAD
    elev_max_rad: float = PAL_ELEV_MAX_RAD
    width_px: int = 1080
    """Panorama width (0: not a panoramic camera, it does not range bodies)."""
    ranged: bool = False
    """Its pose is from mutual calibration: the bands that range it are in view where it stands."""


def plan_camera(sensor_id: str, xy: FloatArray, z_m: float, info: SensorInfo | None, sigma_rad: float) -> PlanCamera:
    """A :class:`PlanCamera` from a known pose and the sensor's SensorInfo (body, lens elevation range)."""
    if info is None:
        return PlanCamera(sensor_id, xy, 0.0, sigma_rad, False, z_m, width_px=0)
    model = info.model
    if isinstance(model, PanoramicModel):
        # tan(e) = (v0 - v) / f_v (common.cameras.CylindricalCamera), rows 0 .. height - 1.
        e_max = math.atan((model.v0_px + 0.5) / model.f_v_px)
        e_min = math.atan((model.v0_px - model.height_px + 0.5) / model.f_v_px)
        return PlanCamera(sensor_id, xy, info.body_radius_m, sigma_rad, info.mobile, z_m, e_min, e_max, model.width_px)
    return PlanCamera(sensor_id, xy, info.body_radius_m, sigma_rad, info.mobile, z_m, width_px=0)


@dataclass(frozen=True, slots=True)
class Scene:
    """One mobile camera's planning problem: itself, the main camera O1, its target, everything else."""

    cam: PlanCamera
    main: PlanCamera
    tgt: PlanTarget
    others: list[PlanCamera]
    """Every other camera where it is, and each other robot also where it is going."""
    people: list[PlanTarget]
    fixed: list[PlanCamera]
    """Every other camera where it will stay: the other robots at their goals (a goal held is judged by these)."""
    others_busy: bool = False
    """Another robot is driving or relearning: one robot moves at a time (unless this one must)."""
