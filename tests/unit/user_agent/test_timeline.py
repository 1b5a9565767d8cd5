"""Who was followed by which track: one row per person, the spans each track followed them, id switches marked,
and each track "the track of" the person it followed most; without ground truth, one row per track."""

from __future__ import annotations

import pytest

from common.schema import TrackSet
from tests.unit.user_agent.recorded_run import EPOCH, track
from user_agent.groundtruth import GroundTruth, GtPoint
from user_agent.timeline import Span, timeline_of_tracks, timeline_with_truth

FPS = 10.0


def _run(owner_of: dict[int, dict[str, str]], frames: int = 30) -> tuple[list[TrackSet], GroundTruth]:
    """People "a" (y = 1) and "b" (y = 4) walking along x; ``owner_of[k]`` says which track sits on whom at k."""
    sets, truth = [], {}
    for k in range(1, frames + 1):
        x = 0.1 * k
        truth[k] = [GtPoint(k, "a", x, 1.0), GtPoint(k, "b", x, 4.0)]
        on = owner_of.get(k, {})
        tracks = [
            track(tid, x, 1.0 if who == "a" else 4.0, EPOCH + round((k - 1) / FPS * 1e9)) for who, tid in on.items()
        ]
        sets.append(TrackSet(manager_id="mgr1", seq=k, stamp_ns=EPOCH + round((k - 1) / FPS * 1e9), tracks=tracks))
    return sets, GroundTruth(truth)


def test_an_id_switch_and_a_missed_stretch_are_on_the_person_s_row() -> None:
    # a: followed by t1 for frames 1-10, missed 11-15, followed by t3 from 16 (a new id: a switch); b: t2 throughout.
    owner = {k: ({"a": "m-1"} if k <= 10 else {"a": "m-3"} if k > 15 else {}) | {"b": "m-2"} for k in range(1, 31)}
    sets, gt = _run(owner)
    tl = timeline_with_truth(sets, gt, epoch_ns=EPOCH, fps=FPS)
    assert tl.with_truth and tl.rows == ["a", "b"]
    a = [s for s in tl.spans if s.row == "a"]
    half = 0.5 / FPS
    assert [(s.track_id, round(s.t0_s, 3), round(s.t1_s, 3)) for s in a] == [
        ("m-1", round(-half, 3), round(0.9 + half, 3)),
        ("", round(1.0 - half, 3), round(1.4 + half, 3)),
        ("m-3", round(1.5 - half, 3), round(2.9 + half, 3)),
    ]
    assert [(s.row, s.from_track, s.to_track, s.t_s) for s in tl.switches] == [("a", "m-1", "m-3", pytest.approx(1.5))]
    assert [s.track_id for s in tl.spans if s.row == "b"] == ["m-2"]
    assert tl.track_person == {"m-1": "a", "m-2": "b", "m-3": "a"}
    assert tl.main_track == {"a": "m-3", "b": "m-2"}  # m-3 followed a for 15 frames, m-1 for 10


def test_a_track_that_jumps_to_another_person_is_coloured_by_whom_it_followed_most() -> None:
    # m-1 follows a for 20 frames, then b for 10 (b's own m-2 is gone): b's row holds a's track at its end.
    owner = {k: {"a": "m-1", "b": "m-2"} if k <= 20 else {"b": "m-1"} for k in range(1, 31)}
    tl = timeline_with_truth(*_run(owner), epoch_ns=EPOCH, fps=FPS)
    assert tl.track_person["m-1"] == "a" and tl.main_track["b"] == "m-2"
    assert [s.track_id for s in tl.spans if s.row == "b"] == ["m-2", "m-1"]
    assert [(s.row, s.from_track, s.to_track) for s in tl.switches] == [("b", "m-2", "m-1")]


def test_without_ground_truth_each_track_has_a_row_with_its_gaps() -> None:
    owner: dict[int, dict[str, str]] = {k: {"a": "m-1"} for k in (*range(1, 11), *range(21, 31))}
    for k in range(5, 9):
        owner.setdefault(k, {})["b"] = "m-2"
    sets, _ = _run(owner)
    tl = timeline_of_tracks(sets, epoch_ns=EPOCH, period_s=1.5 / FPS)
    assert not tl.with_truth and tl.rows == ["m-1", "m-2"] and tl.switches == []
    m1 = [s for s in tl.spans if s.row == "m-1"]
    assert len(m1) == 2 and m1[0].t1_s < 1.0 < 1.9 < m1[1].t0_s  # published, then a gap of a second, then again
    assert tl.tracks == ["m-1", "m-2"]
    assert Span("m-2", "m-2", pytest.approx(0.4 - 0.075), pytest.approx(0.7 + 0.075)) in tl.spans  # type: ignore[arg-type]
