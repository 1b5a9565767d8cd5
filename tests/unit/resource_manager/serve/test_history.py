"""Track history: ids that never repeat across crashes, the segment log with a torn tail, the store."""

from __future__ import annotations

from pathlib import Path

import pytest

from common.errors import ConfigError
from common.schema import Track
from resource_manager.serve.history import IdAllocator, TrackLog, TrackStore, read_segments
from tests.unit.common.tracks import published


def _track(tid: str, t_ns: int, x: float = 0.0) -> Track:
    return published(tid, x, y=0.0, t_ns=t_ns)


def test_id_allocator_never_repeats_across_crashes(tmp_path: Path) -> None:
    a = IdAllocator(tmp_path, "mgr", block=4)
    ids = [a() for _ in range(6)]
    assert ids == [f"mgr-{k}" for k in range(1, 7)]
    b = IdAllocator(tmp_path, "mgr", block=4)  # "crash": no clean shutdown of a
    nxt = b()
    assert int(nxt.split("-")[1]) > 6
    (tmp_path / "next_id").write_text("garbage")
    with pytest.raises(ConfigError, match="integer"):
        IdAllocator(tmp_path, "mgr")


def test_track_log_roundtrip_torn_tail_and_store(tmp_path: Path) -> None:
    log = TrackLog(tmp_path, segment_s=1.0, retain_s=10.0)
    for k in range(30):
        log.append([_track("m-1", k * 100_000_000, x=k), _track("m-2", k * 100_000_000)], k * 100_000_000)
    log.close()
    segs = sorted(tmp_path.glob("tracks-*.log"))
    assert len(segs) == 3
    with segs[-1].open("ab") as fh:
        fh.write(b"\x50\x00\x00\x00partial")  # a record torn by a crash
    back = read_segments(tmp_path, 1_500_000_000)
    assert [t.stamp_ns for t in back] == sorted(t.stamp_ns for t in back)
    assert {t.track_id for t in back} == {"m-1", "m-2"} and len(back) == 30
    store = TrackStore(history_s=1.0, rate_hz=5.0)
    kept = [store.add(t) for t in read_segments(tmp_path, 0) if t.track_id == "m-1"]
    assert sum(kept) == 15  # 10 Hz in, 5 Hz kept
    assert store.latest("m-1") is not None and store.latest("m-1").x_m == 28.0  # type: ignore[union-attr]
    assert [t.x_m for t in store.path("m-1", 2_500_000_000)] == [26.0, 28.0]
    store.prune(3_000_000_000)
    assert all(t.stamp_ns >= 2_000_000_000 for t in store.path("m-1", 0))


def test_the_store_is_bounded_in_memory_whatever_the_number_of_tracks() -> None:
    """Many people passing by (one short track each) fill the store up to its memory bound, never past it; the
    oldest states go first, each track's newest stays the latest."""
    store = TrackStore(history_s=3600.0, rate_hz=5.0, max_mb=0.1)
    cap = store.max_states
    for i in range(3 * cap):
        assert store.add(_track(f"m-{i // 10}", 1_000_000_000 + i * 300_000_000, x=float(i)))
    assert len(store) == cap == sum(len(store.path(t, 0)) for t in store.ids())
    newest = store.latest(f"m-{(3 * cap - 1) // 10}")
    assert newest is not None and newest.x_m == 3 * cap - 1
    assert "m-0" not in store.ids()
    store.prune(10**13)  # and by time: everything older than history_s
    assert len(store) == 0 and not store.ids()
