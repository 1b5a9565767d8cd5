"""The zones benchmark end to end in its quick mode (issue 25, item 6): one manager against four zone managers, and
a zone leader SIGKILLed once, on a small hall (8 cameras, 8 people, a few seconds), all real processes on loopback.

It checks the JSON has every figure, with lenient floors only: the timing goals live in the benchmark
(``python -m benchmarks.bench_zones``) and benchmarks/NOTES.md, never in assertions.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from benchmarks.bench_load import REPO
from tests.support import child_env

pytestmark = [pytest.mark.integration, pytest.mark.timeout(180)]


def _number(x: object) -> bool:
    return isinstance(x, int | float) and not isinstance(x, bool)


def test_bench_zones_quick_reports_every_figure(tmp_path: Path) -> None:
    out = tmp_path / "zones.json"
    argv = [sys.executable, "-m", "benchmarks.bench_zones", "--quick", "--duration", "6", "--kills", "1"]
    proc = subprocess.run(
        [*argv, "--out", str(out)], check=False, cwd=REPO, env=child_env(), capture_output=True, text=True, timeout=170
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    result = json.loads(out.read_text())
    assert json.loads(proc.stdout) == result
    for name in ("single", "zones", "failover"):
        run = result[name]
        assert _number(run["accuracy"]["mota"]) and _number(run["accuracy"]["idf1"]), (name, run["accuracy"])
        assert _number(run["latency_ms"]["p50"]) and _number(run["latency_ms"]["p99"]), (name, run["latency_ms"])
        assert run["published_twice"]["person_instants"] > 0, (name, run["published_twice"])
        assert "share" in run["border_crossings"], (name, run["border_crossings"])
        assert run["fleet"]["sent"] > 0 and _number(run["fleet"]["behind_ms_max"]), (name, run["fleet"])
        assert all(_number(m["tick_ms"]) for m in run["managers"].values()), (name, run["managers"])
        # the fusing thread's CPU per tick: positive, and not more than the wall clock it took
        assert all(0 < m["tick_cpu_ms"] <= m["tick_ms"] * 1.05 + 0.5 for m in run["managers"].values()), run
        if name != "failover":  # every manager published (a standby's split is None)
            assert all(m["latency_split_ms"]["wait_ms"] >= 0 for m in run["managers"].values()), run["managers"]
    assert list(result["single"]["managers"]) == ["mgr-site"]
    assert sorted(m["zone"] for m in result["zones"]["managers"].values()) == ["ne", "nw", "se", "sw"]
    assert result["single"]["accuracy"]["idf1"] > 0.2  # the single manager tracks the small hall at all
    assert result["single"]["frames_lost"] is not None and result["zones"]["frames_lost"] is not None
    (kill,) = result["failover"]["kills"]
    assert 0 < kill["takeover_s"] < 10.0, kill  # the standby took over (the 2 s goal is the benchmark's)
    assert "disturbed" in kill["other_zones"], kill
    cmp = result["zone_vs_single"]
    assert _number(cmp["mota_zones_minus_single"]) and _number(cmp["tick_ratio_max"]), cmp
    assert _number(cmp["tick_cpu_ratio_max"]) and _number(cmp["tick_cpu_ratio_mean"]), cmp
    est = result["hosts_estimate"]
    assert est["as_measured"]["hosts"] >= 1 and est["own_frames_only"]["hosts"] >= 1, est
    assert set(result["targets"]) >= {"takeover_le_2s", "published_twice_le_0_5pct", "crossings_kept_ge_99pct"}
