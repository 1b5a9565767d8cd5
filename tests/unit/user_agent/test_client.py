"""An agent keeps the latest message of at most MAX_KEPT senders per kind: a flood of fresh ids is bounded."""

from __future__ import annotations

from common.schema import Track, TrackSet
from tests.unit.common.tracks import published
from user_agent.client import MAX_KEPT, _keep, merge_history, merge_tracks


def test_keep_bounds_the_table_and_keeps_the_recently_heard() -> None:
    table: dict[str, int] = {}
    _keep(table, "pano1", 0)
    for i in range(10 * MAX_KEPT):
        _keep(table, f"f{i}", i)
        if i % 50 == 0:
            _keep(table, "pano1", i)  # a real sensor, heard every now and then
    assert len(table) == MAX_KEPT
    assert "pano1" in table and list(table)[-1] == f"f{10 * MAX_KEPT - 1}"


def _track(mid: str, tid: str, stamp_ns: int) -> Track:
    return published(tid, 0.0, 0.0, t_ns=stamp_ns, mid=mid)


def test_zone_managers_sets_merge_into_one_row_per_person() -> None:
    west = TrackSet(manager_id="west", seq=1, stamp_ns=10, tracks=[_track("west", "west-1", 10)])
    east = TrackSet(
        manager_id="east", seq=1, stamp_ns=11, tracks=[_track("east", "west-1", 11), _track("east", "east-4", 11)]
    )
    got = merge_tracks([west, east])
    assert [(t.track_id, t.manager_id) for t in got] == [("east-4", "east"), ("west-1", "east")]


def test_a_history_across_a_handoff_is_one_path_in_time() -> None:
    parts = [_track("east", "west-1", 30), _track("west", "west-1", 10), _track("west", "west-1", 20)]
    parts += [_track("east", "west-1", 20)]  # an instant both published
    got = merge_history(parts)
    assert [(t.stamp_ns, t.manager_id) for t in got] == [(10, "west"), (20, "west"), (30, "east")]
