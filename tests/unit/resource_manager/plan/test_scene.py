"""The planner's camera record from a sensor's SensorInfo: the lens' elevation range from its panorama rows."""

from __future__ import annotations

import msgspec
import numpy as np
import pytest

from common.cameras import CylindricalCamera
from common.schema import PanoramicModel, PinholeModel
from resource_manager.plan.scene import PAL_ELEV_MAX_RAD, PAL_ELEV_MIN_RAD, plan_camera
from tests.unit.resource_manager.synth import Cam, info_for

XY = np.array([1.0, 2.0])


@pytest.mark.parametrize(("height_px", "v0_px"), [(162, 93.0), (200, 100.0), (120, 20.0)])
def test_a_panoramic_cameras_elevation_range_spans_its_top_and_bottom_rows(height_px: int, v0_px: float) -> None:
    info = info_for(Cam("r1", 1.0, 2.0, mobile=True, radius=0.2))
    model = PanoramicModel(width_px=1800, height_px=height_px, f_v_px=256.0, v0_px=v0_px)
    info = msgspec.structs.replace(info, model=model)
    cam = plan_camera("r1", XY, 1.1, info, 0.004)
    cyl = CylindricalCamera(1800, height_px, 256.0, v0_px, 1.1)
    # The outer edges of the first and last rows (half a pixel beyond their centres).
    assert cam.elev_max_rad == pytest.approx(cyl.elevation_from_row(-0.5))
    assert cam.elev_min_rad == pytest.approx(cyl.elevation_from_row(height_px - 0.5))
    assert (cam.radius_m, cam.mobile, cam.width_px, cam.z_m, cam.sigma_rad) == (0.2, True, 1800, 1.1, 0.004)


def test_without_sensor_info_or_a_panorama_the_camera_ranges_no_body() -> None:
    bare = plan_camera("c", XY, 1.3, None, 0.004)
    assert (bare.radius_m, bare.mobile, bare.width_px) == (0.0, False, 0)
    assert (bare.elev_min_rad, bare.elev_max_rad) == (PAL_ELEV_MIN_RAD, PAL_ELEV_MAX_RAD)
    model = PinholeModel(width_px=640, height_px=480, k=[500.0, 0.0, 320.0, 0.0, 500.0, 240.0, 0.0, 0.0, 1.0])
    ptz = msgspec.structs.replace(info_for(Cam("p", 0.0, 0.0, radius=0.0)), kind="ptz", model=model)
    cam = plan_camera("p", XY, 2.5, ptz, 0.002)
    assert cam.width_px == 0 and cam.z_m == 2.5
