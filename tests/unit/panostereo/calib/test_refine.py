"""``panostereo calib refine`` on synthetic sites: poses recovered from walkers, robust to clutter, a camera that
sees nobody left alone, ``--fix`` holding the world frame, bad input refused with one clear message."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from common.pinhole import PinholeCamera
from panostereo.calib.cli import refine_site
from panostereo.calib.poses import CameraPose, pose_change
from tests.unit.panostereo.calib.synth import bumped, true_cameras, write_site_dir


def _pose(cam: PinholeCamera) -> CameraPose:
    return CameraPose(np.array(cam.r), cam.center_world, level=False)


def _written(site_dir: Path, cid: str) -> PinholeCamera:
    path = site_dir / "calib" / f"{cid}.json"
    return PinholeCamera.from_calibration(json.loads(path.read_text()), str(path))


def _errors(out: Path, truth: dict[str, PinholeCamera]) -> dict[str, tuple[float, float]]:
    return {cid: pose_change(_pose(cam), _pose(_written(out, cid))) for cid, cam in truth.items()}


@pytest.mark.parametrize(("shift_m", "turn_deg"), [(0.5, 5.0), (1.5, 15.0)])
def test_walkers_recover_the_poses(tmp_path: Path, shift_m: float, turn_deg: float) -> None:
    truth = true_cameras()
    rng = np.random.default_rng(3)
    start = {
        cid: cam if cid == "cam-a" else bumped(cam, shift_m, math.radians(turn_deg), rng) for cid, cam in truth.items()
    }
    site = write_site_dir(tmp_path / "site", start, truth, seed=1)
    report = refine_site(site, tmp_path / "out", fix=["cam-a"])
    for cid, (moved, turned) in _errors(tmp_path / "out", truth).items():
        assert moved < 0.1 and math.degrees(turned) < 0.3, (cid, moved, math.degrees(turned))
    status = {c["sensor_id"]: c for c in report["cameras"]}
    assert status["cam-a"]["status"] == "fixed"
    for cid in ("cam-b", "cam-c", "cam-d"):
        c = status[cid]
        assert c["status"] == "refined"
        assert c["moved_m"] == pytest.approx(shift_m, abs=0.15)
        assert c["residual_after_px"] < c["residual_before_px"]


def test_clutter_does_not_pull(tmp_path: Path) -> None:
    truth = true_cameras()
    rng = np.random.default_rng(5)
    start = {cid: cam if cid == "cam-a" else bumped(cam, 0.5, math.radians(5.0), rng) for cid, cam in truth.items()}
    # Three clutter boxes per camera and frame, where nobody is: as many as the people each camera sees.
    site = write_site_dir(tmp_path / "site", start, truth, clutter_per_frame=3, seed=2)
    refine_site(site, tmp_path / "out", fix=["cam-a"])
    for cid, (moved, turned) in _errors(tmp_path / "out", truth).items():
        assert moved < 0.15 and math.degrees(turned) < 0.5, (cid, moved, math.degrees(turned))


def test_people_walking_in_pairs_do_not_pull_the_poses(tmp_path: Path) -> None:
    # Everyone walks with a companion 0.25 m beside them: closer than the association's rough gate, so early on
    # pairs' boxes are taken for one person, and those wrong pairings must not stay in the final fit.
    truth = true_cameras()
    rng = np.random.default_rng(5)
    start = {cid: cam if cid == "cam-a" else bumped(cam, 0.5, math.radians(5.0), rng) for cid, cam in truth.items()}
    site = write_site_dir(tmp_path / "site", start, truth, people=5, companion_m=0.25, seed=4)
    refine_site(site, tmp_path / "out", fix=["cam-a"])
    for cid, (moved, turned) in _errors(tmp_path / "out", truth).items():
        assert moved < 0.03 and math.degrees(turned) < 0.1, (cid, moved, math.degrees(turned))


def test_a_crowded_room_seen_by_a_real_detector_is_refined(tmp_path: Path) -> None:
    # Four corner cameras over a room of 15 people who hide each other, with what a real detector does (boxes
    # cut where a nearer person begins, noise, misses, clutter, doubled boxes): three cameras start 0.5 m and
    # 5 deg off. Wrong pairings among people closer than the rough gate, and each person's height seen at many
    # instants, once held the cameras metres and degrees from where they are.
    from common.area import rectangle
    from panostereo.datasets.mot import import_mot
    from sim.detector import write_room_dataset

    data = write_room_dataset(tmp_path / "data", people=15, fps=4.0, duration_s=45.0, seed=2)
    site = import_mot(data, tmp_path / "official", fps=4.0, area=rectangle(0.0, 0.0, 8.0, 6.0)).site
    truth = {c: _written(tmp_path / "official", c) for c in ("cam1", "cam2", "cam3", "cam4")}
    rng = np.random.default_rng(1)
    start = {c: cam if c == "cam1" else bumped(cam, 0.5, math.radians(5.0), rng) for c, cam in truth.items()}
    for c, cam in start.items():
        path = tmp_path / "official" / "calib" / f"{c}.json"
        calib = json.loads(path.read_text())
        calib.update(R=cam.r.tolist(), t=cam.t.tolist())
        path.write_text(json.dumps(calib))
    refine_site(site, tmp_path / "out", fix=["cam1"])
    for cid, (moved, turned) in _errors(tmp_path / "out", truth).items():
        assert moved < 0.12 and math.degrees(turned) < 0.6, (cid, moved, math.degrees(turned))


def test_a_camera_that_sees_nobody_is_reported_and_left_as_it_was(tmp_path: Path) -> None:
    truth = true_cameras(away={"cam-d"})
    rng = np.random.default_rng(7)
    start = {cid: cam if cid == "cam-a" else bumped(cam, 0.3, math.radians(3.0), rng) for cid, cam in truth.items()}
    site = write_site_dir(tmp_path / "site", start, truth, seed=3)
    report = refine_site(site, tmp_path / "out", fix=["cam-a"])
    d = next(c for c in report["cameras"] if c["sensor_id"] == "cam-d")
    assert d["status"] == "undetermined" and "too few people" in d["note"]
    assert d["moved_m"] == 0.0 and d["turned_deg"] == 0.0
    written = _written(tmp_path / "out", "cam-d")
    assert np.allclose(written.r, start["cam-d"].r) and np.allclose(written.t, start["cam-d"].t)
    for cid in ("cam-b", "cam-c"):
        moved, turned = _errors(tmp_path / "out", truth)[cid]
        assert moved < 0.1 and math.degrees(turned) < 0.3


def test_fix_keeps_the_world_frame(tmp_path: Path) -> None:
    truth = true_cameras()
    rng = np.random.default_rng(11)
    # Two surveyed cameras a little off the truth: they hold the frame, the others follow them, not the truth.
    start = {cid: bumped(cam, 0.4, math.radians(4.0), rng) for cid, cam in truth.items()}
    start["cam-a"], start["cam-c"] = truth["cam-a"], truth["cam-c"]
    site = write_site_dir(tmp_path / "site", start, truth, seed=4)
    refine_site(site, tmp_path / "out", fix=["cam-a", "cam-c"])
    for cid in ("cam-a", "cam-c"):
        written = _written(tmp_path / "out", cid)
        assert np.allclose(written.r, truth[cid].r, atol=1e-12) and np.allclose(written.t, truth[cid].t, atol=1e-12)
    for cid, (moved, turned) in _errors(tmp_path / "out", truth).items():
        assert moved < 0.1 and math.degrees(turned) < 0.3, (cid, moved, math.degrees(turned))


def test_no_fixed_camera_stays_near_the_guesses_as_a_whole(tmp_path: Path) -> None:
    truth = true_cameras()
    rng = np.random.default_rng(13)
    start = {cid: bumped(cam, 0.3, math.radians(3.0), rng) for cid, cam in truth.items()}
    site = write_site_dir(tmp_path / "site", start, truth, seed=5)
    refine_site(site, tmp_path / "out")
    got = {cid: _written(tmp_path / "out", cid).center_world for cid in truth}
    mean_start = np.mean([start[c].center_world for c in truth], axis=0)
    mean_got = np.mean(list(got.values()), axis=0)
    assert np.linalg.norm(mean_got - mean_start) < 0.3
    # The cameras' layout relative to one another is the true one, up to the scale the guesses leave (the floor
    # and the cameras' heights fix it only loosely when no camera is surveyed).
    for a in truth:
        for b in truth:
            true_d = np.linalg.norm(truth[a].center_world - truth[b].center_world)
            assert np.linalg.norm(got[a] - got[b]) == pytest.approx(true_d, rel=0.02, abs=0.1)


def test_a_panoramic_camera_off_by_half_a_metre_and_10_deg_is_refined_from_a_recording(tmp_path: Path) -> None:
    import tomllib

    from tests.unit.panostereo.calib.synth import PANORAMAS, write_panoramic_recording

    x, y, z, yaw = PANORAMAS["pano3"]
    start = dict(PANORAMAS)
    start["pano3"] = (x + 0.3, y - 0.4, z, yaw + math.radians(10.0))
    site, rec = write_panoramic_recording(tmp_path / "live", start)
    report = refine_site(site, tmp_path / "out", recording=rec, fix=["pano1", "pano2"])
    cam = next(c for c in report["cameras"] if c["sensor_id"] == "pano3")
    assert cam["status"] == "refined" and cam["residual_after_m"] < cam["residual_before_m"]
    pose = tomllib.loads((tmp_path / "out" / "nodes" / "pano3.toml").read_text())["pose"]
    assert math.hypot(pose["x_m"] - x, pose["y_m"] - y) < 0.05 and abs(pose["z_m"] - z) < 0.05
    assert abs(math.remainder(math.radians(pose["yaw_deg"]) - yaw, 2 * math.pi)) < math.radians(1.0)
    text = (tmp_path / "out" / "nodes" / "pano3.toml").read_text()
    assert "# surveyed" in text and 'kind = "sim"' in text  # the rest of the config as it was
    assert (
        tomllib.loads((tmp_path / "out" / "nodes" / "pano1.toml").read_text())["pose"]["x_m"] == PANORAMAS["pano1"][0]
    )


def test_rounds_that_creep_one_way_are_taken_the_rest_of_the_way() -> None:
    """A camera whose last two steps went one way, each 0.8 of the one before, is taken on by the remainder of
    the series (4 times the last step); one whose steps turned, or grew, is left where its adjustment put it, and
    so is every camera once all have settled."""
    from panostereo.calib.adjust import Tolerance
    from panostereo.calib.refine import _extrapolated

    start = CameraPose.from_yaw(0.0, 0.0, 3.0, 0.0)
    step = np.array([0.01, 0.08, 0.0, 0.0])  # yaw (rad), then the centre's shift (m)
    last = {0: step / 0.8, 1: np.array([0.01, -0.08, 0.0, 0.0]) / 0.8, 2: step * 0.5}
    after = [start.moved(step)] * 3
    steps, out, further = _extrapolated([start] * 3, after, [0, 1, 2], last, Tolerance())
    assert further == [0]
    assert np.allclose(steps[0], step)
    assert out[0].centre_m == pytest.approx(start.centre_m + 5.0 * np.array([0.08, 0.0, 0.0]))
    assert out[0].yaw_rad == pytest.approx(start.yaw_rad + 5.0 * 0.01)
    assert out[1] is after[1] and out[2] is after[2]
    # Once every camera has settled the rounds may stop: nobody is left where no adjustment has checked them.
    _, out, further = _extrapolated([start] * 3, after, [0, 1, 2], last, Tolerance(), settled=True)
    assert further == [] and out == after


def test_rounds_associate_only_the_instants_the_adjustment_uses(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """With more person-instants than ``max_people``, the rounds after the first associate every k-th instant (the
    people of the others would not be adjusted): the poses come out as well, and the report still counts every
    instant's people."""
    from common.site import load_site
    from panostereo.calib.observe import from_site
    from panostereo.calib.refine import RefineSettings, refine

    truth = true_cameras()
    rng = np.random.default_rng(17)
    start = {cid: cam if cid == "cam-a" else bumped(cam, 0.5, math.radians(5.0), rng) for cid, cam in truth.items()}
    site = write_site_dir(tmp_path / "site", start, truth, frames=90, seed=6)
    cams, _ = from_site(load_site(site), None)
    every = refine(cams, ["cam-a"])
    caplog.set_level("INFO", logger="panostereo.calib.refine")
    few = refine(cams, ["cam-a"], RefineSettings(max_people=120))
    people = [int(r.getMessage().split(", ")[1].split()[0]) for r in caplog.records if "people (mean" in r.getMessage()]
    assert people[0] >= 3 * 120 and all(120 <= p < people[0] / 2 for p in people[1:]), people
    for cid, got in zip(truth, few.poses, strict=True):
        moved, turned = pose_change(got, _pose(truth[cid]))
        assert moved < 0.05 and math.degrees(turned) < 0.2, (cid, moved, math.degrees(turned))
    for a, b in zip(few.cameras, every.cameras, strict=True):
        assert a.people == pytest.approx(b.people, rel=0.05), (a.sensor_id, a.people, b.people)


def test_the_refinement_runs_on_one_blas_thread(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Its adjustments' linear algebra runs on one BLAS thread (tall, thin matrices: more threads cost CPU time and
    save none), and the process's own limit is back afterwards."""
    from threadpoolctl import threadpool_info

    import panostereo.calib.refine as refine_mod
    from common.site import load_site
    from panostereo.calib.observe import from_site

    def blas_threads() -> set[int]:
        return {p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"}

    seen: list[set[int]] = []
    adjust = refine_mod.adjust

    def watched(*args: object, **kwargs: object) -> object:
        seen.append(blas_threads())
        return adjust(*args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(refine_mod, "adjust", watched)
    truth = true_cameras()
    site = write_site_dir(tmp_path / "site", truth, truth, frames=20, seed=7)
    cams, _ = from_site(load_site(site), None)
    before = blas_threads()
    refine_mod.refine(cams, ["cam-a"])
    assert seen and all(s == {1} for s in seen), seen
    assert blas_threads() == before
