"""The zones benchmark's measure of people published by two managers at once (benchmarks/bench_zones.py)."""

from __future__ import annotations

from benchmarks.bench_zones import GT_HZ, duplicates
from common.schema import TrackSet
from tests.unit.common.tracks import T0, published
from user_agent.groundtruth import GroundTruth, GtPoint

EPOCH = T0 - int(1e9 / GT_HZ)
"""Frame 2 is T0."""


def _set(mid: str, *tracks: tuple[str, float, float]) -> TrackSet:
    return TrackSet(
        manager_id=mid, seq=1, stamp_ns=T0, tracks=[published(t, x, y, 0.0, T0, mid=mid) for t, x, y in tracks]
    )


def _gt(*people: tuple[str, float, float]) -> GroundTruth:
    return GroundTruth(frames={2: [GtPoint(2, pid, x, y) for pid, x, y in people]})


def test_two_people_side_by_side_each_published_by_one_manager_are_not_published_twice() -> None:
    gt = _gt(("p1", 10.0, 5.0), ("p2", 10.3, 5.0))
    got = duplicates([_set("west", ("west-1", 10.0, 5.0)), _set("east", ("east-1", 10.3, 5.0))], gt, EPOCH)
    assert got["person_instants"] == 2 and got["by_several"] == 0, got
    assert got["near_several"] == 2  # each has both managers' tracks within the match distance


def test_one_person_published_by_two_managers_under_two_ids_is() -> None:
    """Under one id (a handover's overlap) an agent shows them once: counted apart, as ``same_id_share``."""
    gt = _gt(("p1", 10.0, 5.0), ("p2", 14.0, 5.0))
    sets = [_set("west", ("west-1", 10.0, 5.0)), _set("east", ("west-1", 10.1, 5.0), ("east-2", 14.0, 5.0))]
    got = duplicates(sets, gt, EPOCH)
    assert got["person_instants"] == 2 and got["by_several"] == 0 and got["same_id_share"] == 0.5, got
    sets = [_set("west", ("west-1", 10.0, 5.0)), _set("east", ("east-1", 10.1, 5.0), ("east-2", 14.0, 5.0))]
    got = duplicates(sets, gt, EPOCH)
    assert got["by_several"] == 1 and got["share"] == 0.5 and got["same_id_share"] == 0.0, got
    # One manager's own two tracks of a person are its tracker's doing, not two managers publishing.
    got = duplicates([_set("west", ("west-1", 10.0, 5.0), ("west-2", 10.1, 5.0))], gt, EPOCH)
    assert got["by_several"] == 0, got
