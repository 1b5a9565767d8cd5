"""CLEAR-MOT / ID measures: a published known answer, and behaviour on positions."""

from __future__ import annotations

import math

import numpy as np
import pytest

from common.schema import Track, TrackSet, TrackState
from tests.unit.common.tracks import published
from user_agent.evaluate import (
    HypPoint,
    MotAccumulator,
    evaluate_positions,
    hypotheses_from_tracksets,
    within_area,
    within_area_many,
)
from user_agent.groundtruth import GroundTruth, GtPoint

NAN = math.nan


def _readme_accumulator(frames: int = 3) -> tuple[MotAccumulator, list[list[tuple[str, str, str, float]]]]:
    """The worked example of py-motmetrics' README ("Populating the accumulator")."""
    acc = MotAccumulator()
    steps = [
        (["1", "2"], ["1", "2", "3"], [[0.1, NAN, 0.3], [0.5, 0.2, 0.3]]),
        (["1", "2"], ["1"], [[0.2], [0.4]]),
        (["1", "2"], ["1", "3"], [[0.6, 0.2], [0.1, 0.6]]),
    ]
    events = [acc.update(*step) for step in steps[:frames]]
    return acc, events


def test_readme_events_match_published_ones() -> None:
    _, ev = _readme_accumulator()
    # Published: frame 0 MATCH 1-1 0.1, MATCH 2-2 0.2, FP 3; frame 1 MATCH 1-1 0.2, MISS 2;
    # frame 2 MATCH 1-1 0.6 (continuity beats the cheaper 1-3), SWITCH 2-3 0.6.
    assert [(t, o, h) for t, o, h, _ in ev[0]] == [("MATCH", "1", "1"), ("MATCH", "2", "2"), ("FP", "", "3")]
    assert [(t, o, h) for t, o, h, _ in ev[1]] == [("MATCH", "1", "1"), ("MISS", "2", "")]
    assert [(t, o, h, d) for t, o, h, d in ev[2]] == [("MATCH", "1", "1", 0.6), ("SWITCH", "2", "3", 0.6)]


@pytest.mark.parametrize(
    ("frames", "mota", "motp", "idf1", "recall", "precision", "fp", "fn", "ids", "mt", "pt"),
    [
        # py-motmetrics README, motchallenge summary: "full" and "part" (frames 0-1) rows.
        (3, 0.5, 0.34, 5 / 6, 5 / 6, 5 / 6, 1, 1, 1, 1, 1),
        (2, 0.5, 0.5 / 3, 0.75, 0.75, 0.75, 1, 1, 0, 1, 1),
    ],
)
def test_readme_summary_matches_published_figures(
    frames: int,
    mota: float,
    motp: float,
    idf1: float,
    recall: float,
    precision: float,
    fp: int,
    fn: int,
    ids: int,
    mt: int,
    pt: int,
) -> None:
    acc, _ = _readme_accumulator(frames)
    m = acc.summary()
    assert m.frames == frames
    assert m.mota == pytest.approx(mota)
    assert m.motp_m == pytest.approx(motp)
    assert m.idf1 == pytest.approx(idf1)
    assert m.idp == pytest.approx(idf1) and m.idr == pytest.approx(idf1)
    assert m.recall == pytest.approx(recall)
    assert m.precision == pytest.approx(precision)
    assert (m.false_positives, m.misses, m.id_switches) == (fp, fn, ids)
    assert (m.mostly_tracked, m.partially_tracked, m.mostly_lost) == (mt, pt, 0)


def _gt(frames: dict[int, list[tuple[str, float, float]]]) -> GroundTruth:
    return GroundTruth({k: [GtPoint(k, i, x, y) for i, x, y in v] for k, v in frames.items()})


def test_perfect_tracking_scores_one_and_zero_error() -> None:
    gt = _gt({k: [("a", k * 0.1, 0.0), ("b", 3.0, k * 0.1)] for k in range(1, 11)})
    hyps = {k: [HypPoint("m-1", p.x_m, p.y_m), HypPoint("m-2", q.x_m, q.y_m)] for k, (p, q) in gt.frames.items()}
    m = evaluate_positions(gt, hyps, threshold_m=0.5)
    assert (m.mota, m.idf1, m.precision, m.recall) == (1.0, 1.0, 1.0, 1.0)
    assert m.motp_m == 0.0 and m.p90_error_m == 0.0 and m.id_switches == 0


def test_threshold_turns_far_tracks_into_miss_plus_false_positive() -> None:
    gt = _gt({1: [("a", 0.0, 0.0)], 2: [("a", 0.0, 0.0)]})
    hyps = {1: [HypPoint("t1", 0.3, 0.0)], 2: [HypPoint("t1", 0.7, 0.0)]}
    m = evaluate_positions(gt, hyps, threshold_m=0.5)
    assert (m.matches, m.misses, m.false_positives) == (1, 1, 1)
    assert m.mota == pytest.approx(0.0)
    assert m.mean_error_m == pytest.approx(0.3)


def test_swapped_identities_count_one_switch_each_and_lower_idf1() -> None:
    frames = {k: [("a", 0.0, 0.0), ("b", 2.0, 0.0)] for k in range(1, 5)}
    gt = _gt(frames)
    hyps = {k: [HypPoint("t1", 0.0, 0.0), HypPoint("t2", 2.0, 0.0)] for k in (1, 2)}
    hyps |= {k: [HypPoint("t2", 0.0, 0.0), HypPoint("t1", 2.0, 0.0)] for k in (3, 4)}
    m = evaluate_positions(gt, hyps)
    assert m.id_switches == 2
    assert m.mota == pytest.approx(1 - 2 / 8)
    assert m.idf1 == pytest.approx(0.5)


def _track(tid: str, x: float, vx: float, state: TrackState = "confirmed") -> Track:
    return published(tid, x, y=0.0, vx=vx, t_ns=0, state=state)


def test_tracksets_are_aligned_to_frames_with_velocity_and_span() -> None:
    epoch = 1_000_000_000_000
    sets = [
        TrackSet(manager_id="m", seq=i, stamp_ns=epoch + int((0.5 + i * 0.1) * 1e9), tracks=[_track("m-1", i, 1.0)])
        for i in range(5)
    ] + [TrackSet(manager_id="m", seq=9, stamp_ns=epoch + int(0.9e9), tracks=[_track("m-2", 5.0, 0.0, "tentative")])]
    # fps 10: frame k <-> (k-1)/10 s; the sets span 0.5..0.9 s: frames 1..12 are scored (up to the last set
    # plus the 0.25 s gap); frames 1..3, before the first set and beyond the gap, have no tracks: misses.
    hyps, scored = hypotheses_from_tracksets(sets, epoch, 10.0, range(1, 30), max_gap_s=0.25)
    assert scored == list(range(1, 13))
    assert hyps[1] == hyps[2] == hyps[3] == []
    assert hyps[4] == [HypPoint("m-1", -0.2, 0.0)]  # 0.3 s: the first set, 0.2 s back by its velocity
    assert hyps[6] == [HypPoint("m-1", 0.0, 0.0)]  # frame 6 = 0.5 s: first set, no extrapolation
    (p,) = hyps[7]  # 0.6 s: second set (x=1)
    assert p.x_m == pytest.approx(1.0)
    assert hyps[11] == []  # tentative tracks are not scored
    _, late = hypotheses_from_tracksets(sets, epoch, 10.0, range(1, 30), max_gap_s=0.25, start_ns=epoch + int(0.7e9))
    assert late == list(range(8, 13))  # a warm-up end at 0.7 s drops frames 1..7


def test_an_id_two_zone_managers_published_near_one_frame_is_one_hypothesis() -> None:
    epoch = 1_000_000_000_000
    # The west manager's last set with w-1 at 0.46 s; the east's first at 0.52 s (its own instants): frame 6 (0.5 s)
    # is nearest to both, and scores one w-1, the east's (nearer in time).
    sets = [
        TrackSet(manager_id="west", seq=1, stamp_ns=epoch + int(0.46e9), tracks=[_track("w-1", 5.9, 1.0)]),
        TrackSet(manager_id="east", seq=1, stamp_ns=epoch + int(0.52e9), tracks=[_track("w-1", 6.0, 1.0)]),
        TrackSet(manager_id="east", seq=2, stamp_ns=epoch + int(0.52e9), tracks=[_track("e-1", 8.0, 0.0)]),
    ]
    hyps, _ = hypotheses_from_tracksets(sets[:2], epoch, 10.0, [6], max_gap_s=0.25)
    (p,) = hyps[6]
    assert p.track_id == "w-1" and p.x_m == pytest.approx(5.98)
    hyps, _ = hypotheses_from_tracksets([sets[0], sets[2]], epoch, 10.0, [6], max_gap_s=0.25)
    assert sorted(h.track_id for h in hyps[6]) == ["e-1", "w-1"]  # different people: both


def test_fragmentations_and_ids_per_person_count_interruptions_and_the_ids_each_person_had() -> None:
    acc = MotAccumulator()
    near, far = [[0.1]], [[math.nan]]
    for hyp, d in [("a", far), ("a", near), ("a", far), ("a", near), ("b", near), ("b", far), ("b", near)]:
        acc.update(["p"], [hyp], d)
    m = acc.summary(0.5)
    assert m.fragmentations == 2 and m.id_switches == 1 and m.ids_per_person == 2.0


def test_points_within_a_convex_area_grown_by_a_margin() -> None:
    """A point is in the scored area inside the polygon or within the margin of its edge (corners rounded)."""
    square = np.array([[0.0, 0.0], [8.0, 0.0], [8.0, 6.0], [0.0, 6.0]])
    pts = np.array([[4.0, 3.0], [8.4, 3.0], [8.6, 3.0], [-0.4, -0.2], [8.4, 6.4], [4.0, -0.5], [4.0, -0.51]])
    inside = within_area_many(square, pts, 0.5)
    assert inside.tolist() == [True, True, False, True, False, True, False]
    assert [within_area(square, x, y, 0.5) for x, y in pts] == inside.tolist()
    assert within_area_many(square, np.zeros((0, 2)), 0.5).shape == (0,)
