"""The shell's pieces that need no network: latest-frame slot, wiring from configs, simulated goals."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import pytest

from common.frames import Frame
from common.schema import ViewPlan
from common.site import load_site
from sensor_node.build import build_node
from sensor_node.config import load_node_config
from sensor_node.node import LatestSlot
from sim.source import SimFrames
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
    sim = parts.source
    assert parts.kind == "panoramic" and isinstance(sim, SimFrames) and parts.pose is None
    assert parts.plans is sim.plans and parts.ptz is None
    site = load_site(REPO / "deploy/sites/demo.toml")
    spec = site.camera_by_id("pano1")
    assert spec.mobile
    world = sim.world
    start = world.platform_at("pano1", 5.0)

    def plan(sensor_id: str, x_m: float, y_m: float, stamp_ns: int) -> ViewPlan:
        return ViewPlan(manager_id="mgr", seq=0, stamp_ns=stamp_ns, sensor_id=sensor_id, partner_id="pano2",
                        track_id="mgr-1", goal_x_m=x_m, goal_y_m=y_m, baseline_m=2.0, phi1_rad=1.0,
                        predicted_error_m=0.1, current_error_m=0.2)  # fmt: skip

    # A view plan for pano1 issued at world time 1 s: the simulated robot drives there.
    parts.plans.follow(plan("pano1", start.x_m + 1.0, start.y_m, sim.epoch_ns + 1_000_000_000))
    parts.plans.follow(plan("nobody", 1.0, 1.0, now))  # not in this world: ignored
    stop = threading.Event()
    frame = sim.read(stop)
    assert frame is not None and frame.image is not None and frame.image.shape == (576, 768, 3)
    assert frame.ptz is None
    assert sim.plans.goals_applied == 1
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
    assert isinstance(parts.source, SimFrames) and parts.source.world.seed == (site.site.seed if seed is None else seed)
    # The camera height a robot node publishes in SensorInfo (its x, y, yaw come from mutual calibration).
    assert parts.camera_height_m == pytest.approx(site.camera_by_id("pano1").height_m)
