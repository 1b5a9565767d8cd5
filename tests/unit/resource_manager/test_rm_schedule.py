"""When the manager fuses (resource_manager/ingest/schedule.py): the watermark of its sensors' frames."""

from __future__ import annotations

import pytest

from common.schema import Features, PanoramicModel, SensorInfo
from resource_manager.config import ManagerConfig, ManagerSection
from resource_manager.fusion import Batch, Fusion
from resource_manager.ingest.schedule import Watermark

MS = 1_000_000
T0 = 1_800_000_000_000_000_000
PERIOD = 100 * MS  # 10 fps
W = Watermark(allowance_ns=200 * MS, min_interval_ns=0)


@pytest.mark.parametrize(
    ("newest_ms", "now_ms", "last_ms", "want_ms"),
    [
        ({"a": 1000, "b": 1000}, 1010, 900, 1000),  # both reached 1000: fuse it
        ({"a": 1000, "b": 900}, 1010, 800, 900),  # b is behind: fuse what both reached
        ({"a": 1000, "b": 900}, 1010, 900, None),  # ... and nothing new until b's next frame
        ({"a": 1000, "b": 900}, 1150, 900, None),  # b's next frame is due at 1000: 150 ms late is within the allowance
        ({"a": 1000, "b": 900}, 1210, 900, 1000),  # 310 ms late: not waited for any longer
        ({"a": 1000}, 1010, 0, 1000),  # the first fusion
        ({}, 1010, 0, None),  # nobody: nothing to fuse
        ({"a": 2000, "b": 1990}, 1500, 0, 1500),  # frames stamped ahead of the clock: never past now
    ],
)
def test_the_watermark(newest_ms: dict[str, int], now_ms: int, last_ms: int, want_ms: int | None) -> None:
    newest = {s: t * MS for s, t in newest_ms.items()}
    got = W.instant(newest, dict.fromkeys(newest, PERIOD), now_ms * MS, last_ms * MS)
    assert got == (None if want_ms is None else want_ms * MS)


def test_the_rate_is_capped() -> None:
    capped = Watermark(allowance_ns=200 * MS, min_interval_ns=50 * MS)
    newest = {"a": 1030 * MS}
    assert capped.instant(newest, {"a": 10 * MS}, 1031 * MS, 1000 * MS) is None  # 30 ms after the last: wait
    assert capped.instant({"a": 1060 * MS}, {"a": 10 * MS}, 1061 * MS, 1000 * MS) == 1060 * MS


def _info(sid: str) -> SensorInfo:
    model = PanoramicModel(width_px=1080, height_px=162, f_v_px=256.0, v0_px=93.0)
    return SensorInfo(sensor_id=sid, seq=0, stamp_ns=T0, kind="panoramic", model=model, fps=10.0)


def _frame(sid: str, seq: int, t_ms: int) -> Features:
    return Features(sensor_id=sid, seq=seq, stamp_ns=T0 + t_ms * MS, frame_index=seq)


def _fusion() -> Fusion:
    fusion = Fusion(ManagerConfig(manager=ManagerSection(id="m1", rate_hz=100.0, latency_ms=200.0)))
    fusion.absorb(Batch(infos=[_info("a"), _info("b")]))
    return fusion


def test_a_sensor_that_stops_holds_the_others_back_only_until_its_deadline() -> None:
    fusion = _fusion()
    instants = []
    for k in range(1, 21):  # b stops after 1.0 s
        frames = [_frame("a", k, 100 * k)] + ([_frame("b", k, 100 * k)] if k <= 10 else [])
        fusion.absorb(Batch(features=frames))
        t = fusion.next_instant(T0 + (100 * k + 5) * MS)
        if t is not None:
            fusion.step(Batch(), t)
            instants.append((t - T0) // MS)
    assert instants[:10] == [100 * k for k in range(1, 11)]  # in step with both cameras
    assert 1100 not in instants and 1200 not in instants  # waited for b's frames 1100, 1200 (due, not late yet)
    assert instants[-1] == 2000  # then on with a alone: b is 800 ms overdue


def test_a_frame_300_ms_late_is_dropped_once_its_instant_is_fused_and_never_rewinds() -> None:
    """b's frame of 200 ms arrives 300 ms late, at 500 ms. With a 200 ms allowance the manager stops waiting for b
    at 400 ms (its next frame was due at 200) and fuses a alone; the late frame's instant is then behind: it is
    counted and dropped, and b's next frames are used again."""
    fusion = _fusion()
    fusion.absorb(Batch(features=[_frame("a", 1, 100), _frame("b", 1, 100)]))
    t1 = fusion.next_instant(T0 + 105 * MS)
    assert t1 == T0 + 100 * MS
    fusion.step(Batch(), t1)
    fused = []
    for k in range(2, 5):
        fusion.absorb(Batch(features=[_frame("a", k, 100 * k)]))
        t = fusion.next_instant(T0 + (100 * k + 5) * MS)
        if t is not None:
            fusion.step(Batch(), t)
            fused.append((t - T0) // MS)
    assert fused == [400]  # waited for b until its deadline (200 + 200 ms), then a alone
    late_before = fusion.ingest.counters.late
    fusion.absorb(Batch(features=[_frame("b", 2, 200), _frame("a", 5, 500), _frame("b", 3, 500)]))
    assert fusion.ingest.counters.late == late_before + 1  # the 200 ms frame: its instant was fused
    t2 = fusion.next_instant(T0 + 505 * MS)
    assert t2 == T0 + 500 * MS  # b back in step
    assert not fusion.step(Batch(), t2).skipped
    assert fusion.step(Batch(), T0 + 300 * MS).skipped  # never rewinds


def test_out_of_order_frames_are_sorted_and_a_clock_step_restarts_a_sensor() -> None:
    fusion = _fusion()
    fusion.absorb(Batch(features=[_frame("a", 2, 200), _frame("a", 1, 100), _frame("b", 1, 100), _frame("b", 2, 200)]))
    assert fusion.next_instant(T0 + 205 * MS) == T0 + 200 * MS
    assert fusion.ingest.counters.out_of_order == 1
    fusion.step(Batch(), T0 + 200 * MS)
    # b's clock steps back 2 s (a newer seq, an older stamp): its buffer restarts, a is not held back by it forever.
    fusion.absorb(Batch(features=[_frame("a", 3, 300), _frame("b", 3, -1800)]))
    assert fusion.ingest.counters.clock_steps == 1
    t = fusion.next_instant(T0 + 305 * MS)
    assert t == T0 + 300 * MS  # b's newest is far behind: late, not waited for
