"""Ingest buffers: frames kept in capture order whatever the arrival order; duplicates, late frames, clock steps and
overflow counted."""

from __future__ import annotations

import pytest

from common.schema import Features
from resource_manager.ingest.buffers import Ingest

S = 1_000_000_000


def _frame(seq: int, stamp_ns: int, sensor_id: str = "p1") -> Features:
    return Features(sensor_id=sensor_id, seq=seq, stamp_ns=stamp_ns, frame_index=seq)


@pytest.mark.parametrize(
    ("arrivals", "kinds", "stamps"),
    [
        ([(1, 1), (2, 2), (3, 3)], ["accepted"] * 3, [1, 2, 3]),
        ([(1, 1), (3, 3), (2, 2)], ["accepted", "accepted", "out_of_order"], [1, 2, 3]),
        ([(1, 1), (1, 1)], ["accepted", "duplicate"], [1]),
        # seq goes up but the stamp jumps 5 s back: the sender's clock was stepped, its buffer restarts
        ([(1, 10), (2, 11), (3, 5)], ["accepted", "accepted", "clock_step"], [5]),
    ],
)
def test_frames_are_kept_sorted_by_stamp(arrivals: list[tuple[int, int]], kinds: list[str], stamps: list[int]) -> None:
    ingest = Ingest(capacity=8)
    got = [ingest.add(_frame(seq, t_s * S)) for seq, t_s in arrivals]
    assert got == kinds
    assert ingest.buffers["p1"].stamps == [t * S for t in stamps]


def test_overflow_drops_the_oldest_and_bracket_finds_the_neighbours() -> None:
    ingest = Ingest(capacity=3)
    for k in range(5):
        ingest.add(_frame(k, k * S))
    buf = ingest.buffers["p1"]
    assert buf.stamps == [2 * S, 3 * S, 4 * S] and ingest.counters.dropped == 2
    before, after = buf.bracket(3 * S + S // 2)
    assert before is not None and after is not None and (before.seq, after.seq) == (3, 4)
    assert buf.bracket(S) == (None, buf.frames[0])
    prev = buf.previous(buf.frames[2])
    assert prev is not None and prev.seq == 3


def test_a_frame_behind_the_last_fusion_is_late_and_trim_keeps_what_can_bracket() -> None:
    ingest = Ingest(capacity=8)
    for k in (1, 2, 3, 4):
        ingest.add(_frame(k, k * S))
    ingest.last_fusion_ns = 3 * S
    assert ingest.add(_frame(0, 2 * S + 1)) == "out_of_order" and ingest.counters.late == 1  # kept: a lower bracket
    assert ingest.add(_frame(10, 5 * S)) == "accepted"
    ingest.trim(3 * S + 1)
    # the frame at or before the instant brackets it, the one before that extrapolates; older ones go
    assert ingest.buffers["p1"].stamps == [2 * S + 1, 3 * S, 4 * S, 5 * S]
    ingest.forget("p1")
    assert "p1" not in ingest.buffers
