"""Accuracy through the real network on the simulated sites (issue 6, item 10), with lenient bounds.

Each case is a short seeded ``panostereo demo`` run (router, one OS process per camera rendering pixels, the
manager), scored by the agent's evaluator against the simulator's ground truth. The sites, manager variants and
scoring are those of ``benchmarks/bench_accuracy.py``, which reports the real figures over longer runs; the
bounds here are regression guards, looser than the issue's goals because a short run scores few frames: one
lost-and-reborn track in an 18 s one-person run costs ~0.2 MOTA (a CI run scored 0.78 with 2.9 cm mean error).
"""

from __future__ import annotations

import importlib.util
from pathlib import Path
from typing import Any

import pytest

from benchmarks.bench_accuracy import PAPER1_ROBOT_POSE, PARKED, REPO, demo, manager_variant, site_with_manager
from tests.support import skip_or_fail

pytestmark = pytest.mark.integration

SITES = REPO / "deploy" / "sites"

# name: (site, manager variant (None: the site's own), seconds, {metric: (">=" | "<=", bound)})
CASES: dict[str, tuple[str, str | None, float, dict[str, tuple[str, float]]]] = {
    # The paper's two-camera geometry, one person; issue goals 5 cm surveyed, 10 cm by mutual calibration.
    "paper1_surveyed": ("paper1.toml", PARKED + PAPER1_ROBOT_POSE, 18,
                        {"mean_error_m": ("<=", 0.08), "mota": (">=", 0.6)}),
    "paper1_mutual": ("paper1.toml", PARKED, 18, {"mean_error_m": ("<=", 0.12), "mota": (">=", 0.6)}),
    # Two people; issue goal 10 cm.
    "paper2": ("paper2.toml", PARKED, 20, {"mean_error_m": ("<=", 0.15), "mota": (">=", 0.6)}),
    # Six people, four cameras; issue goals MOTA 0.97, IDF1 0.95.
    "six": ("six.toml", None, 25, {"mota": (">=", 0.85), "idf1": (">=", 0.7), "mean_error_m": ("<=", 0.12)}),
}  # fmt: skip


@pytest.mark.parametrize("name", sorted(CASES))
def test_network_accuracy_on_simulated_site(name: str, tmp_path: Path) -> None:
    if importlib.util.find_spec("resource_manager.node") is None:
        skip_or_fail("the resource manager is not installed")
    site_file, variant, seconds, bounds = CASES[name]
    site = SITES / site_file
    manager = manager_variant(site, tmp_path, variant, name) if variant is not None else None
    row: dict[str, Any] = demo(site_with_manager(site, tmp_path, manager), tmp_path, seconds, name)
    assert "error" not in row, row
    assert row["frames"] >= 8 * 15, row  # at least 8 s scored at the sites' 15 fps
    for metric, (op, bound) in bounds.items():
        value = row[metric]
        ok = value >= bound if op == ">=" else value <= bound
        assert ok, f"{name}: {metric} = {value} (want {op} {bound}); {row}"
