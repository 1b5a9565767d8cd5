"""The simulated camera source: renders a site's camera from the simulated world.

The pipeline sees only the rendered pixels. What a real node would have from
calibration -- the annular model and the cylindrical camera -- comes from the
renderer's ``models``; the world's ground truth never reaches the pipeline.

Timing: frame k shows world time ``k / fps`` and is stamped ``epoch + k / fps``
on the node's clock (the launcher gives every process the same epoch), so
stamps mean the same instant in every process. If rendering falls behind, the
source skips to the current slot and counts the skipped frames.

Closed loop: mobile robots drive to the goals of the manager's view plans. The
node feeds every plan it receives to the source's :attr:`SimFrames.plans`
(:class:`sim.driver.PlanFollower`); the world applies goals from their issue
time, so every simulated camera renders the same robot trajectories.
"""

from __future__ import annotations

import logging
import math
import threading
import zlib
from typing import Any

import numpy as np

from common.cameras import AnnularModel, CylindricalCamera, PtzCamera
from common.frames import Clock, Frame, Pacer
from common.schema import SourceState
from common.site import CameraSpec, SiteConfig
from sim.driver import PlanFollower
from sim.ptz_head import SimulatedPtz
from sim.world import World

__all__ = ["SimFrames", "noise_seed"]

logger = logging.getLogger(__name__)


def noise_seed(site_seed: int, camera_id: str, seed: int = -1) -> int:
    """The sensor-noise seed: ``seed`` if >= 0, else derived from the site seed and camera id."""
    return seed if seed >= 0 else (site_seed * 1_000_003 + zlib.crc32(camera_id.encode())) % (2**32)


class SimFrames:
    """Renders one camera of a simulated site at a fixed rate.

    Args:
        site: the site (world and true camera placements).
        camera_id: which ``[[camera]]`` to render.
        fps: frames per second (0: the site's).
        epoch_ns: world time 0 on the node clock.
        seed: sensor-noise seed (-1: derived).
        clock: the node clock.
        ptz: the simulated head (PTZ cameras).
    """

    def __init__(
        self,
        site: SiteConfig,
        camera_id: str,
        *,
        fps: float,
        epoch_ns: int,
        seed: int,
        clock: Clock,
        ptz: SimulatedPtz | None = None,
    ) -> None:
        from sim.render.cameras import PanoramicRenderer, PtzRenderer

        self.site = site
        self.spec: CameraSpec = site.camera_by_id(camera_id)
        self.world = World.from_site(site)
        self.fps = fps or site.site.fps
        self.epoch_ns = epoch_ns
        self.clock = clock
        self.ptz = ptz
        self.rng = np.random.default_rng(noise_seed(site.site.seed, camera_id, seed))
        self._renderer: Any
        if self.spec.kind == "panoramic":
            self._renderer = PanoramicRenderer(self.world, self.spec, site.world.lighting)
        else:
            self._renderer = PtzRenderer(self.world, self.spec)
        self._pacer = Pacer(self.fps, clock, epoch_ns)
        self.plans = PlanFollower(self.world, site, epoch_ns)
        """Takes the manager's view plans: the mobile robots of this world drive to their goals."""
        self.state: SourceState = "starting"
        self.message = ""

    @property
    def kind(self) -> str:
        return self.spec.kind

    @property
    def models(self) -> tuple[AnnularModel, CylindricalCamera]:
        """The panoramic camera's calibration (annular model, cylindrical camera)."""
        models: tuple[AnnularModel, CylindricalCamera] = self._renderer.models
        return models

    def ptz_camera(self, x_m: float, y_m: float, z_m: float) -> PtzCamera:
        """The PTZ head's camera model at a (surveyed) position, in its initial pointing."""
        w, h = self.spec.image_size
        return PtzCamera(
            x_m,
            y_m,
            z_m,
            int(w),
            int(h),
            math.radians(self.spec.hfov_deg),
            math.radians(self.spec.pan_deg),
            math.radians(self.spec.tilt_deg),
            self.spec.zoom,
        )

    def read(self, stop: threading.Event) -> Frame | None:
        slot = self._pacer.wait(stop)
        if slot is None:
            return None
        k, stamp, skipped = slot
        self.plans.apply()
        t_s = k / self.fps
        pose = None
        if self.spec.kind == "panoramic":
            image = self._renderer.render(t_s, self.rng)
        else:
            assert self.ptz is not None
            pose = self.ptz.pose(stamp)
            image = self._renderer.render(t_s, pose.pan_rad, pose.tilt_rad, pose.zoom, self.rng)
        self.state, self.message = "ok", ""
        return Frame(index=k, stamp_ns=stamp, image=image, skipped=skipped, ptz=pose)

    def close(self) -> None:
        """Nothing is held open."""
