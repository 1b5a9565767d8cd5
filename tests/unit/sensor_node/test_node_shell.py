"""The shell's pieces that need no network: latest-frame slot, wiring from configs, simulated goals."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import pytest

from common.site import load_site
from sensor_node.build import build_node
from sensor_node.config import load_node_config
from sensor_node.node import LatestSlot
from sensor_node.sources import Frame
from tests.support import REPO


def test_latest_slot_drops_old_frames_never_queues() -> None:
    slot = LatestSlot()
    for k in range(5):
        slot.put(Frame(index=k, stamp_ns=k))
    f = slot.get(0.1)
    assert f is not None and f.index == 4 and slot.dropped == 4
    assert slot.get(0.01) is None
    got: list[Frame | None] = []
    t = threading.Thread(target=lambda: got.append(slot.get(5.0)))
    t.start()
    time.sleep(0.05)
    slot.put(Frame(index=9, stamp_ns=9))
    t.join(2.0)
    assert got and got[0] is not None and got[0].index == 9
    slot.close()
    assert slot.get(5.0) is None and slot.closed


def test_sim_example_builds_a_panoramic_node_and_obeys_goals(tmp_path: Path) -> None:
    cfg = load_node_config(REPO / "deploy/nodes/examples/sim.toml")
    now = time.time_ns()
    parts = build_node(cfg, lambda: now)
    assert parts.kind == "panoramic" and parts.sim is not None and parts.pose is None
    site = load_site(REPO / "deploy/sites/demo.toml")
    spec = site.camera_by_id("pano1")
    assert spec.mobile
    world = parts.sim.world
    start = world.platform_at("pano1", 5.0)
    # A view plan for pano1 issued at world time 1 s: the simulated robot drives there.
    parts.sim.add_goal("pano1", start.x_m + 1.0, start.y_m, parts.sim.epoch_ns + 1_000_000_000)
    parts.sim.add_goal("nobody", 1.0, 1.0, now)  # not in this world: ignored
    stop = threading.Event()
    frame = parts.sim.read(stop)
    assert frame is not None and frame.image is not None and frame.image.shape == (576, 768, 3)
    assert parts.sim.goals_applied == 1
    later = world.platform_at("pano1", 31.0)
    assert abs(later.x_m - (start.x_m + 1.0)) < 0.05
    features, state = parts.processor.process_frame(frame, 0)
    assert features.sensor_id == "pano1" and state == "warmup"
    assert features.stamp_ns == frame.stamp_ns


@pytest.mark.parametrize("seed", [None, 42])
def test_sim_world_follows_panostereo_seed(seed: int | None, monkeypatch: pytest.MonkeyPatch) -> None:
    if seed is None:
        monkeypatch.delenv("PANOSTEREO_SEED", raising=False)
    else:
        monkeypatch.setenv("PANOSTEREO_SEED", str(seed))
    cfg = load_node_config(REPO / "deploy/nodes/examples/sim.toml")
    parts = build_node(cfg, time.time_ns)
    site = load_site(REPO / "deploy/sites/demo.toml")
    assert parts.sim is not None and parts.sim.world.seed == (site.site.seed if seed is None else seed)
    # The camera height a robot node publishes in SensorInfo (its x, y, yaw come from mutual calibration).
    assert parts.camera_height_m == pytest.approx(site.camera_by_id("pano1").height_m)
