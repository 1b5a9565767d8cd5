"""Building a node from its config: each source kind gives its processor, camera model and pose, and the
SensorInfo says how the pose is known."""

from __future__ import annotations

import json
import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from common.errors import ConfigError
from common.schema import PanoramicModel, PinholeModel
from sensor_node.build import BOX_POINT_SIGMA_M, HEAD_POINT_SIGMA_M, build_node, sensor_info
from sensor_node.config import load_node_config
from tests.support import REPO

EXAMPLES = REPO / "deploy" / "nodes" / "examples"
NOW_NS = 1_700_000_000_000_000_000

PANORAMIC_CAMERA = """
[camera]
model = "panoramic"
image_size = [768, 576]
center_px = [388.0, 284.0]
radial_poly = [254.0, -1.06, 0.0008]
pano_size = [1080, 162]
f_v_px = 234.0
v0_px = 84.7
height_m = 1.1
"""


def _folder_node(tmp_path: Path, pose: str, at_end: str = "stay") -> Path:
    (tmp_path / "frames").mkdir(exist_ok=True)
    cv2.imwrite(str(tmp_path / "frames" / "0001.png"), np.zeros((576, 768, 3), np.uint8))
    path = tmp_path / "cam.toml"
    path.write_text(
        '[node]\nid = "cam2"\n[source]\nkind = "folder"\npath = "frames"\nglob = "*.png"\nfps = 10.0\n'
        f'at_end = "{at_end}"\n' + PANORAMIC_CAMERA + pose
    )
    return path


@pytest.mark.parametrize(("pose_z", "height_m"), [(None, 1.1), (1.45, 1.45)])
def test_a_panoramic_camera_takes_its_height_from_the_surveyed_pose(
    tmp_path: Path, pose_z: float | None, height_m: float
) -> None:
    pose = "" if pose_z is None else f"[pose]\nx_m = 7.5\ny_m = 5.5\nz_m = {pose_z}\nyaw_deg = 270\n"
    cfg = load_node_config(_folder_node(tmp_path, pose, at_end="exit"))
    parts = build_node(cfg, lambda: NOW_NS)
    assert parts.kind == "panoramic" and isinstance(parts.model, PanoramicModel)
    assert parts.camera_height_m == pytest.approx(height_m) and parts.exit_at_end and parts.fps == 10.0
    info = sensor_info(cfg, parts, seq=3, stamp_ns=NOW_NS)
    assert (info.sensor_id, info.seq, info.fps, info.point_sigma_m) == ("cam2", 3, 10.0, HEAD_POINT_SIGMA_M)
    assert info.blobs_merge  # foreground segments: people who overlap in the picture may come as one blob
    if pose_z is None:
        assert parts.pose is None and info.pose is None and info.pose_source == "unknown"
    else:
        assert parts.pose is not None and parts.pose.yaw_rad == pytest.approx(-math.pi / 2)
        assert info.pose == parts.pose and info.pose_source == "surveyed"


def test_a_detection_file_node_is_a_pinhole_camera_at_its_calibrated_centre(tmp_path: Path) -> None:
    k = [[800.0, 0.0, 320.0], [0.0, 800.0, 240.0], [0.0, 0.0, 1.0]]
    r = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])  # looking along world +x
    centre = np.array([1.0, 2.0, 2.5])
    cal = {"model": "pinhole", "image_size": [640, 480], "K": k, "dist": [], "R": r.tolist(),
           "t": (-r @ centre).tolist()}  # fmt: skip
    (tmp_path / "cal.json").write_text(json.dumps(cal))
    (tmp_path / "det.txt").write_text("1,-1,300,200,40,120,0.9\n")
    path = tmp_path / "c1.toml"
    path.write_text('[node]\nid = "c1"\n[source]\nkind = "detections"\nfile = "det.txt"\ncalibration = "cal.json"\n'
                    "fps = 2.0\nepoch_ns = 1\n")  # fmt: skip
    cfg = load_node_config(path)
    parts = build_node(cfg, lambda: NOW_NS)
    assert parts.kind == "pinhole" and isinstance(parts.model, PinholeModel) and parts.fps == 2.0
    assert parts.pose is not None
    assert (parts.pose.x_m, parts.pose.y_m, parts.pose.z_m) == pytest.approx(tuple(centre))
    info = sensor_info(cfg, parts, seq=0, stamp_ns=NOW_NS)
    assert info.pose_source == "surveyed" and info.point_sigma_m == BOX_POINT_SIGMA_M  # a box, not a head
    assert not info.blobs_merge  # a person detector's boxes: one per person
    assert info.shared_detector == ""  # ...this camera's own
    path.write_text(path.read_text() + 'shared_detector = "mvdetr"\n')
    shared = load_node_config(path)
    assert sensor_info(shared, build_node(shared, lambda: NOW_NS), seq=0, stamp_ns=NOW_NS).shared_detector == "mvdetr"
    path.write_text(path.read_text().replace('"mvdetr"', '"MV DeTr"'))
    with pytest.raises(ConfigError, match="shared_detector"):
        load_node_config(path)


def test_a_mobile_sim_camera_sends_its_height_and_leaves_its_place_to_mutual_calibration() -> None:
    cfg = load_node_config(EXAMPLES / "sim.toml")
    parts = build_node(cfg, lambda: NOW_NS)
    info = sensor_info(cfg, parts, seq=0, stamp_ns=NOW_NS)
    assert parts.pose is None and info.mobile and info.pose_source == "mutual"
    assert parts.camera_height_m > 0.0
    assert info.pose is not None and info.pose.z_m == pytest.approx(parts.camera_height_m)


def test_a_simulated_ptz_head_needs_its_surveyed_pose(tmp_path: Path) -> None:
    cfg = load_node_config(EXAMPLES / "ptz.toml")
    parts = build_node(cfg, lambda: NOW_NS)
    assert parts.kind == "ptz" and parts.ptz is not None and isinstance(parts.model, PinholeModel)
    assert parts.pose is not None and parts.pose.z_m == pytest.approx(2.4)
    text = (EXAMPLES / "ptz.toml").read_text()
    without = tmp_path / "ptz.toml"
    without.write_text(
        text.split("[pose]")[0].replace("../../sites/demo.toml", str(REPO / "deploy" / "sites" / "demo.toml"))
    )
    with pytest.raises(ConfigError, match=r"needs a \[pose\] table"):
        build_node(load_node_config(without), lambda: NOW_NS)
