"""Zones (issue 25, item 1's definition): a manager started for one zone of a site fuses the cameras that see into
it, and only those. Real processes on loopback (test_faults.py's site: detection-file nodes around a 10 m room)."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from common.site import load_site, zone_sensor_ids
from tests.integration.test_faults import make_fault_site, observing, running
from tests.support import wait_for

pytestmark = [pytest.mark.integration, pytest.mark.timeout(120)]


def test_a_zone_manager_fuses_only_the_cameras_that_see_into_its_zone(tmp_path: Path, request: pytest.FixtureRequest):  # type: ignore[no-untyped-def]
    with running(make_fault_site(tmp_path, prefix="zones"), request) as site:
        site_file = site.zoned_site_file("zones", {"west": (0.0, 5.0), "east": (5.0, 10.0)}, reach_m=1.0)
        west = zone_sensor_ids(load_site(site_file), "west")
        assert 0 < len(west) < len(site.ids), west  # the room's east camera is no west camera
        site.start_router()
        with observing(site) as obs:
            for sid in site.ids:
                site.start_node(sid)
            site.start_manager(extra=("--site", str(site_file), "--zone", "west"))
            t0 = time.monotonic()

            def fused() -> bool:
                st = [m for m in obs.status_since(t0) if m.tracks and m.sensors_in_use]
                return bool(st) and st[-1].sensors_expected == west and set(st[-1].sensors_in_use) <= set(west)

            wait_for(fused, 45.0, f"the west manager tracking with {west} only")
            sets = obs.sets_since(t0)
            assert sets and all(set(s.sensors_used) <= set(west) for s in sets), [s.sensors_used for s in sets[-3:]]
