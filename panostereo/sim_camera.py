"""The ``[source] kind = "sim"`` builder: a sensor node whose camera is one of a simulated site's.

The sensor node knows sources only by kind (:data:`sensor_node.build.SOURCES`); this module wires the
simulator (:mod:`sim`) into it, so that ``sensor_node`` never imports ``sim``. ``pyproject.toml`` names
:func:`build_simulated` under the ``panostereo.sources`` entry points, and the node loads it the first time a
config asks for a ``sim`` source.
"""

from __future__ import annotations

import math

from common.cameras import CylindricalCamera
from common.errors import ConfigError
from common.frames import Clock
from common.schema import Pose
from common.site import load_site, site_file
from sensor_node.build import SAME_HEIGHT_M, ImageProcessor, NodeParts, panoramic_pipeline
from sensor_node.config import NodeConfig, SimSource, epoch_from
from sensor_node.features import PinholeGeometry
from sensor_node.pipeline import ImagePipeline
from sensor_node.ptz import PtzHead
from sim.ptz_head import SimulatedPtz
from sim.source import SimFrames
from sim.world import site_with_seed_from_env

__all__ = ["build_simulated"]


def build_simulated(cfg: NodeConfig, src: SimSource, pose: Pose | None, clock: Clock) -> NodeParts:
    """A camera of a simulated site: rendered pixels, a simulated PTZ head, robots that follow the plans.

    Raises:
        ConfigError: a simulated PTZ camera without a ``[pose]`` table.
    """
    where = cfg.path or "node config"
    # PANOSTEREO_SEED (``panostereo demo --seed N``) picks the world the ground truth is written for.
    site = site_with_seed_from_env(load_site(site_file(src.site, cfg.path or "node.toml")))
    cam_id = src.camera or cfg.node.id
    spec = site.camera_by_id(cam_id)
    epoch = epoch_from(src.epoch_ns, clock())
    fps = src.fps or site.site.fps
    if spec.kind == "panoramic":
        sim = SimFrames(site, cam_id, fps=fps, epoch_ns=epoch, seed=src.seed, clock=clock)
        annular, cyl = sim.models
        if pose is not None and abs(pose.z_m - cyl.height_m) > SAME_HEIGHT_M:
            cyl = CylindricalCamera(cyl.width_px, cyl.height_px, cyl.f_v_px, cyl.v0_px, pose.z_m, cyl.direction)
        proc = ImageProcessor(panoramic_pipeline(cfg, annular, cyl))
        return NodeParts(
            sim, proc, "panoramic", cyl.to_model(), pose, fps, plans=sim.plans, camera_height_m=cyl.height_m
        )
    if pose is None:
        raise ConfigError(f"{where}: a simulated PTZ camera needs a [pose] table (the head's surveyed position)")
    driver = SimulatedPtz(math.radians(spec.pan_deg), math.radians(spec.tilt_deg), spec.zoom, clock)
    sim = SimFrames(site, cam_id, fps=fps, epoch_ns=epoch, seed=src.seed, clock=clock, ptz=driver)
    head = PtzHead(driver, sim.ptz_camera(pose.x_m, pose.y_m, pose.z_m))
    geo = PinholeGeometry(head.camera(driver.pose(clock())))
    pipe = ImagePipeline(cfg.node.id, geo, cfg.pipeline)
    ptz_pose = Pose(x_m=pose.x_m, y_m=pose.y_m, z_m=pose.z_m, yaw_rad=0.0)
    return NodeParts(sim, ImageProcessor(pipe, head), "ptz", geo.camera.to_model(), ptz_pose, fps, head, sim.plans)
