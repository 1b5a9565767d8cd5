"""``panostereo calib refine`` from the command line: the refined site runs, bad input gets one clear error."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from common.errors import ConfigError
from panostereo.calib.cli import format_report, refine_site
from panostereo.cli import main
from tests.unit.panostereo.calib.synth import bumped, true_cameras, write_site_dir


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


def test_the_report_reads_as_a_table(tmp_path: Path) -> None:
    truth = true_cameras()
    site = write_site_dir(tmp_path / "site", truth, truth, frames=20, seed=10)
    text = format_report(refine_site(site, tmp_path / "out", fix=["cam-a"]))
    lines = text.splitlines()
    assert lines[0].startswith("refined site: ")
    assert lines[1].split()[:2] == ["camera", "status"]
    assert next(ln for ln in lines if ln.startswith("cam-a")).split()[1] == "fixed"
