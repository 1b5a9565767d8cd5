"""``panostereo calib refine`` on synthetic sites: poses recovered from walkers, robust to clutter, a camera that
sees nobody left alone, ``--fix`` holding the world frame, bad input refused with one clear message."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from common.errors import ConfigError
from common.pinhole import PinholeCamera
from panostereo.calib.cli import refine_site
from panostereo.calib.poses import CameraPose, pose_change
from panostereo.cli import main
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


def test_the_refined_site_runs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    truth = true_cameras()
    rng = np.random.default_rng(17)
    start = {cid: cam if cid == "cam-a" else bumped(cam, 0.3, math.radians(3.0), rng) for cid, cam in truth.items()}
    site = write_site_dir(tmp_path / "site", start, truth, seed=6)
    assert main(["calib", "refine", str(site), "--out", str(tmp_path / "out"), "--fix", "cam-a", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert Path(report["site"]) == (tmp_path / "out" / "site.toml").resolve()
    assert main(["evaluate-site", report["site"], "--json"]) == 0
    scores = json.loads(capsys.readouterr().out)["scores"]
    assert scores[0]["mota"] > 0.5


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["missing/site.toml"], "missing/site.toml"),
        (["SITE", "--fix", "cam-z"], "--fix cam-z: not a camera"),
        (["SITE", "--frames", "-3"], "--frames must be >= 0"),
        (["SITE", "--recording", "NOT_MCAP"], "not a readable MCAP recording"),
        (["SITE", "--recording", "missing.mcap"], "no such recording"),
        (["PLAIN"], "not a dataset site"),
    ],
)
def test_bad_input_gets_one_clear_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], message: str
) -> None:
    truth = true_cameras()
    site = write_site_dir(tmp_path / "site", truth, truth, frames=10, seed=8)
    (tmp_path / "not.mcap").write_text("not a recording\n")
    plain = tmp_path / "plain.toml"
    plain.write_text('[site]\nname = "plain"\n')
    subst = {"SITE": str(site), "NOT_MCAP": str(tmp_path / "not.mcap"), "PLAIN": str(plain)}
    argv = ["calib", "refine", *(subst.get(a, a) for a in args), "--out", str(tmp_path / "out")]
    assert main(argv) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0], err


def test_refine_site_refuses_out_inside_the_site(tmp_path: Path) -> None:
    truth = true_cameras()
    site = write_site_dir(tmp_path / "site", truth, truth, frames=10, seed=9)
    with pytest.raises(ConfigError, match="--out"):
        refine_site(site, tmp_path / "site", fix=["cam-a"])
