"""A dataset site through the live network gives the figures ``evaluate-site`` gives in dataset time.

The first 40 annotated frames of Wildtrack (7 real calibrated cameras, its ground-truth boxes as detections,
2 fps) are imported, played through real processes (router, seven detection nodes, the manager, the recorder)
with ``panostereo demo --site``, and scored; the same site played offline must score the same within run-to-run
noise. The demo plays from frame 1 once every process is up, whatever the start-up took, and scores from there.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from panostereo.datasets.play import evaluate_site
from panostereo.datasets.wildtrack import import_wildtrack
from tests.support import REPO, free_port, skip_or_fail

pytestmark = pytest.mark.integration

WILDTRACK = REPO.parent / "shared" / "datasets" / "wildtrack"
FRAMES = 40


def test_live_network_matches_dataset_time(tmp_path: Path) -> None:
    if not (WILDTRACK / "annotations_positions").is_dir():
        skip_or_fail(f"Wildtrack annotations not found at {WILDTRACK}")
    site = import_wildtrack(WILDTRACK, tmp_path / "site", max_frames=FRAMES).site
    offline, _ = evaluate_site(site, thresholds_m=(0.5,))
    out = tmp_path / "run"
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "panostereo",
            "demo",
            "--site",
            str(site),
            "--out",
            str(out),
            "--no-view",
            "--listen",
            f"tcp/127.0.0.1:{free_port()}",
        ],
        capture_output=True,
        text=True,
        timeout=FRAMES / 2 + 120,
        check=False,
        cwd=REPO,
    )
    logs = "".join(f"--- {p.name}\n{p.read_text()[-2000:]}" for p in sorted((out / "logs").glob("*.log")))
    assert proc.returncode == 0, f"{proc.stdout[-2000:]}\n{proc.stderr[-2000:]}\n{logs}"
    live = json.loads((out / "summary.json").read_text())
    want = offline["scores"][0]
    assert live["scored_from_s"] == 0.0 and live["frames"] >= FRAMES - 1  # from frame 1, whatever the start-up
    assert want["mota"] > 0.7  # the offline figure itself is sound
    # Within run-to-run noise: a live instant fused without a camera whose frame came past its deadline under
    # load (the runs: benchmarks/NOTES.md).
    assert abs(live["mota"] - want["mota"]) <= 0.05, (live, want)
    assert abs(live["idf1"] - want["idf1"]) <= 0.05, (live, want)
