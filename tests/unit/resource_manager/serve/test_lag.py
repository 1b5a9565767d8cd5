"""Tracks published late: each instant once ``lag`` has passed, a tentative start under the id it got later."""

from __future__ import annotations

from resource_manager.serve.lag import LaggedTracks
from resource_manager.track.tracker import TrackSnapshot
from tests.unit.resource_manager.synth import snapshot

S = 1_000_000_000


def _snap(serial: int, t_s: float, track_id: str = "", *, placed: bool = True) -> TrackSnapshot:
    return snapshot(
        serial, track_id=track_id, t_ns=int(t_s * S), hits=1, placed=placed, reported=bool(track_id) and placed
    )


def test_an_instant_is_due_once_the_lag_has_passed_one_per_call() -> None:
    lag = LaggedTracks(2 * S)
    for k in range(4):
        lag.push(k, k * S, ["c1"], [_snap(1, k, "m-1")])
    assert lag.due(1 * S) is None
    first = lag.due(3 * S)
    assert first is not None and (first.seq, first.t_ns) == (0, 0)
    second = lag.due(3 * S)
    assert second is not None and second.seq == 1 and lag.due(3 * S) is None
    assert [i.seq for i in lag.flush()] == [2, 3] and len(lag) == 0


def test_a_tentative_start_goes_out_under_the_id_it_was_confirmed_with_never_confirmed_ones_not_at_all() -> None:
    lag = LaggedTracks(5 * S)
    lag.push(0, 0, [], [_snap(1, 0.0), _snap(2, 0.0), _snap(3, 0.0, placed=False)])
    lag.push(1, S, [], [_snap(1, 1.0, "m-7"), _snap(3, 1.0, "m-8")])  # 1 took a lost person's id back
    (early, late) = lag.flush()
    assert [(tr.serial, tid) for tr, tid in early.tracks] == [(1, "m-7")]  # 2 never confirmed; 3 too vague then
    assert sorted(tid for _, tid in late.tracks) == ["m-7", "m-8"]
