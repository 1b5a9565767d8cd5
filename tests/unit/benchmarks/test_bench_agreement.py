"""The cameras' agreement check over a played room, as benchmarks/bench_agreement.py measures it: a camera whose
calibration no longer fits its pictures is named, and in place none is."""

from __future__ import annotations

import math
from pathlib import Path

from benchmarks.bench_agreement import Played, flagged, moved
from common.area import rectangle
from panostereo.datasets.mot import import_mot
from resource_manager.poses.agreement import AgreementParams
from sim.detector import write_room_dataset


def test_a_bumped_camera_of_a_played_room_is_named_and_in_place_none_is(tmp_path: Path) -> None:
    data = write_room_dataset(tmp_path / "data", people=6, fps=4.0, duration_s=30.0, seed=3)
    site = import_mot(data, tmp_path / "site", fps=4.0, area=rectangle(0.0, 0.0, 8.0, 6.0)).site
    run = flagged(Played.of(site))
    in_place, residual = run["flagged"], run["residual_m"]
    assert set(in_place) == {"cam1", "cam2", "cam3", "cam4"}
    assert max(in_place.values()) == 0.0 and max(residual.values()) < 0.2, (in_place, residual)
    bumped = moved(site, tmp_path / "bumped", "cam2", 0.5, math.radians(5.0), seed=1)
    run = flagged(Played.of(bumped))
    shares, residual = run["flagged"], run["residual_m"]
    assert shares["cam2"] > 0.5 and residual["cam2"] > 0.5, (shares, residual)
    assert max(v for sid, v in shares.items() if sid != "cam2") < shares["cam2"], shares


def test_a_camera_bumped_while_the_room_is_played_is_named_against_its_own_residual(tmp_path: Path) -> None:
    """Half-way through, cam2's blobs and SensorInfo become those of a calibration 0.3 m and 3 degrees off: too
    little for the absolute threshold, but its residual grows well past its own in place, learned before."""
    data = write_room_dataset(tmp_path / "data", people=6, fps=4.0, duration_s=90.0, seed=3)
    site = import_mot(data, tmp_path / "site", fps=4.0, area=rectangle(0.0, 0.0, 8.0, 6.0)).site
    bumped = moved(site, tmp_path / "bumped", "cam2", 0.3, math.radians(3.0), seed=1)
    bumped_cam2 = next(c for c in Played.of(bumped).cameras if c.sensor_id == "cam2")
    run = flagged(Played.of(site), bumped=bumped_cam2)
    assert max(run["flagged"].values()) == 0.0, run  # nothing named before the bump
    after = run["flagged_after"]
    assert after["cam2"] > 0.5 and max(v for sid, v in after.items() if sid != "cam2") < after["cam2"], run
    assert run["settled_m"]["cam2"] is not None and run["residual_m"]["cam2"] < AgreementParams().disagree_m, run
