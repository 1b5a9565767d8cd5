"""Playing an imported dataset through the fusion (panostereo/datasets/play.py): deterministic, scored from the first
frame, a one-camera false box is no person, the scored area is where the ground truth annotates."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from common.area import rectangle
from common.errors import ConfigError
from panostereo.datasets.mot import import_mot
from panostereo.datasets.play import evaluate_site
from tests.unit.panostereo.mot_synth import look_at, write_dataset
from user_agent.evaluate import within_area
from user_agent.groundtruth import read_gt_csv


def test_evaluate_site_is_deterministic_and_scores_from_the_first_frame(made: Path, tmp_path: Path) -> None:
    site = import_mot(made, tmp_path / "site", fps=5.0).site
    one, run1 = evaluate_site(site)
    _, run2 = evaluate_site(site)
    assert [ts.tracks for ts in run1.tracksets] == [ts.tracks for ts in run2.tracksets]  # identical tracks
    s05, s10 = one["scores"]
    assert s05["threshold_m"] == 0.5 and s10["threshold_m"] == 1.0
    assert s05["frames"] == 30 and s05["objects"] == 90  # every ground-truth frame, from the first
    assert s05["mota"] >= 0.9 and s05["idf1"] >= 0.9 and s05["id_switches"] == 0
    assert s05["mean_error_m"] < 0.1
    assert one["scored_area"] == "ground_truth" and len(one["scores_everywhere"]) == 2


def test_a_false_box_in_one_camera_is_no_person(tmp_path: Path) -> None:
    write_dataset(tmp_path / "data", clutter=True)
    report, _ = evaluate_site(import_mot(tmp_path / "data", tmp_path / "site", fps=5.0).site)
    s = report["scores_everywhere"][0]
    assert s["false_positives"] <= 3 and s["mota"] >= 0.9


def test_the_scored_area_is_where_the_ground_truth_annotates(made: Path) -> None:
    area = read_gt_csv(made / "gt.csv").area()
    assert area is not None
    assert within_area(area, 4.0, 5.0, 0.5)  # among the people
    assert within_area(area, 1.0 - 0.3, 3.0, 0.5) and not within_area(area, -2.0, 3.0, 0.5)


def test_a_declared_area_scores_every_track_and_a_lag_is_reported_beside_the_live_figures(
    made: Path, tmp_path: Path
) -> None:
    site = import_mot(made, tmp_path / "site", fps=5.0, area=rectangle(-5.0, -5.0, 15.0, 15.0)).site
    report, run = evaluate_site(site, publish_lag_s=1.0)
    assert report["scored_area"] == "everywhere" and report["scores"] == report["scores_everywhere"]
    assert report["publish_lag_s"] == 1.0 and report["tracks_ended_inside"] == 0
    live, late = report["live"]["scores"][0], report["scores"][0]
    assert late["objects"] == live["objects"] and late["mota"] >= live["mota"] - 0.02  # every frame, flushed at the end
    assert len(run.tracksets) == 30
    with pytest.raises(ConfigError, match="publish-lag"):
        evaluate_site(site, publish_lag_s=-1.0)


def test_a_multi_view_detector_that_misses_everyone_for_a_frame_loses_nobody(made: Path, tmp_path: Path) -> None:
    """Every camera's boxes of frames 15-17 are gone (0.6 s of a detector's bad moment). Each camera's own detector:
    three views miss everyone at once, frame after frame, which ends every track, and the people come back under new
    ids. One multi-view detector drawn into the three views: one miss a frame, the ids hold; evaluate-site reports
    the recall it learnt."""
    for det in (made / "detections").glob("*.txt"):
        kept = [line for line in det.read_text().splitlines() if line.split(",")[0] not in ("15", "16", "17")]
        det.write_text("".join(line + "\n" for line in kept))
    own, _ = evaluate_site(import_mot(made, tmp_path / "own", fps=5.0).site)
    shared, _ = evaluate_site(import_mot(made, tmp_path / "shared", fps=5.0, shared_detector="drawn").site)
    assert own["scores"][0]["track_ids"] > 3 and own["shared_detector_recall"] == {}
    assert shared["scores"][0]["track_ids"] == 3 and shared["scores"][0]["id_switches"] == 0
    assert 0.8 < shared["shared_detector_recall"]["drawn"] < 0.95  # it missed everyone in 3 of 30 frames


def test_a_camera_off_its_calibration_is_named_by_the_agreement_check(tmp_path: Path) -> None:
    """16 s of three people seen by three cameras: with every calibration right, every camera agrees; with the east
    camera's calibration saying it stands 1 m along its wall from where its boxes were taken (looking the same way),
    the east camera disagrees, all the time."""
    write_dataset(tmp_path / "data", frames=80)
    right, _ = evaluate_site(import_mot(tmp_path / "data", tmp_path / "right", fps=5.0).site)
    assert {r["sensor_id"] for r in right["agreement"]} == {"north", "east", "southwest"}
    assert all(r["disagreed_share"] == 0.0 and r["residual_m"] < 0.2 for r in right["agreement"]), right["agreement"]
    (tmp_path / "data" / "calib" / "east.json").write_text(json.dumps(look_at(14.0, 6.0, 3.0, (5.0, 6.0))))
    off, _ = evaluate_site(import_mot(tmp_path / "data", tmp_path / "off", fps=5.0).site)
    worst = off["agreement"][0]
    assert worst["sensor_id"] == "east", off["agreement"]
    assert worst["disagreed_share"] > 0.5 and worst["residual_m"] > 0.3, off["agreement"]
