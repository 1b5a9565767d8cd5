"""Blobs become foot and head rays in the camera's own frame; cameras without a surveyed pose are left out."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from common.errors import ConfigError
from common.schema import Blob, Features, PanoramicModel, Pose, SensorInfo
from common.site import load_site
from panostereo.calib.observe import camera_pose, from_features, from_recording, from_site
from tests.unit.panostereo.calib.synth import PANORAMAS, true_cameras, write_panoramic_recording, write_site_dir


def test_pinhole_rays_pass_through_the_box_bottom_centre(tmp_path: Path) -> None:
    truth = true_cameras()
    site = write_site_dir(tmp_path / "site", truth, truth, frames=10, seed=1)
    cams, notes = from_site(load_site(site))
    assert notes == [] and [c.sensor_id for c in cams] == list(truth)
    c = cams[0]
    cam = truth[c.sensor_id]
    assert np.allclose(c.pose.centre_m, cam.center_world) and not c.pose.level
    assert c.head_plane is not None
    # Where the foot ray meets the floor projects back to the box's bottom centre: a point of the ray.
    f_world = c.foot[0] @ c.pose.rotation
    t = -c.pose.centre_m[2] / f_world[2]
    floor = c.pose.centre_m + t * f_world
    uv, _ = cam.project(floor[None])
    again = (floor - c.pose.centre_m) @ c.pose.rotation.T
    assert np.allclose(again / np.linalg.norm(again), c.foot[0]) and np.isfinite(uv).all()
    assert np.allclose(np.linalg.norm(c.head_plane, axis=1), 1.0)
    assert np.allclose(np.einsum("ij,ij->i", c.head_plane, c.head), 0.0, atol=1e-9)


def _panoramic_info(**kw: object) -> SensorInfo:
    model = PanoramicModel(width_px=1080, height_px=162, f_v_px=256.0, v0_px=93.0)
    base: dict[str, object] = {"pose": Pose(x_m=1.0, y_m=2.0, z_m=1.1, yaw_rad=0.5), "pose_source": "surveyed"}
    base.update(kw)
    return SensorInfo(sensor_id="pano1", seq=0, stamp_ns=1, kind="panoramic", model=model, **base)  # type: ignore[arg-type]


def test_level_rays_come_from_bearing_and_elevations() -> None:
    blob = Blob(local_id=3, bearing_rad=0.25, width_rad=0.1, top_elev_rad=0.2, bottom_elev_rad=-0.3, bbox_u_px=0.0,
                bbox_v_px=5.0, bbox_w_px=10.0, bbox_h_px=40.0, confidence=0.3)  # fmt: skip
    rays = from_features(_panoramic_info(), [(7, Features(sensor_id="pano1", seq=1, stamp_ns=1, frame_index=0,
                                                          blobs=[blob]))])  # fmt: skip
    assert rays is not None and rays.pose.level and rays.pose.yaw_rad == pytest.approx(0.5)
    assert rays.instant.tolist() == [7] and rays.track.tolist() == [3]
    assert rays.foot[0] == pytest.approx(
        [math.cos(-0.3) * math.cos(0.25), math.cos(-0.3) * math.sin(0.25), math.sin(-0.3)]
    )
    assert not rays.head_ok[0]  # a low-confidence blob: its head may be above the picture


@pytest.mark.parametrize("kw", [{"mobile": True, "pose_source": "mutual"}, {"pose": None}])
def test_a_camera_with_no_surveyed_pose_is_left_out(kw: dict[str, object]) -> None:
    assert camera_pose(_panoramic_info(**kw)) is None


def test_a_recording_puts_every_camera_on_common_instants(tmp_path: Path) -> None:
    site, rec = write_panoramic_recording(tmp_path, PANORAMAS, seconds=3.0)
    cams, notes = from_recording(rec, load_site(site))
    assert notes == [] and sorted(c.sensor_id for c in cams) == sorted(PANORAMAS)
    assert all(c.instant.max() == 29 and np.unique(c.instant).size == 30 for c in cams)
    few, _ = from_recording(rec, load_site(site), frames=10)
    assert all(np.unique(c.instant).size == 10 for c in few)


def test_a_recording_without_the_sites_cameras_is_refused(tmp_path: Path) -> None:
    _, rec = write_panoramic_recording(tmp_path, PANORAMAS, seconds=1.0)
    other = tmp_path / "other.toml"
    other.write_text(
        '[site]\nname = "other"\n\n[[process]]\nname = "x"\ncommand = "node"\nconfig = "nodes/pano1.toml"\n'
    )
    (tmp_path / "nodes" / "pano1.toml").write_text('[node]\nid = "cam9"\n')
    with pytest.raises(ConfigError, match="holds no Features of the site's cameras"):
        from_recording(rec, load_site(other))
