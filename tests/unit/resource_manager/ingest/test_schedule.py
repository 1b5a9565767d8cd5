"""When the manager fuses (resource_manager/ingest/schedule.py): the watermark of its sensors' frames."""

from __future__ import annotations

import pytest

from common.schema import Features, PanoramicModel, SensorInfo
from resource_manager.config import ManagerConfig, ManagerSection
from resource_manager.fusion import Batch, Fusion
from resource_manager.ingest.schedule import (
    MIN_ALLOWANCE_NS,
    WARMUP_FRAMES,
    WINDOW_FRAMES,
    FrameTiming,
    ScheduleParams,
    Scheduler,
)

MS = 1_000_000
T0 = 1_800_000_000_000_000_000
PERIOD = 100 * MS  # 10 fps
WAIT = 200 * MS


def _scheduler(timings: dict[str, FrameTiming], mode: str = "watermark", min_interval_ns: int = 0) -> Scheduler:
    return Scheduler(ScheduleParams(mode=mode, max_wait_ns=WAIT, min_interval_ns=min_interval_ns), timings)  # type: ignore[arg-type]


def _at(newest_ms: int, late_ms: float = 0.0) -> FrameTiming:
    """A sensor at 10 fps whose newest frame is stamped ``newest_ms``, and whose recent frames all came ``late_ms``
    after their expected time."""
    timing = FrameTiming(
        declared_period_ns=PERIOD,
        newest_ns=newest_ms * MS,
        arrival_ns=int((newest_ms + late_ms) * MS),
        delay_ns=late_ms * MS,
        frames=WINDOW_FRAMES,
    )
    timing.lateness.extend([late_ms * MS] * WINDOW_FRAMES)
    return timing


@pytest.mark.parametrize(
    ("newest_ms", "now_ms", "last_ms", "want_ms"),
    [
        ({"a": 1000, "b": 1000}, 1010, 900, 1000),  # both reached 1000: fuse it
        ({"a": 1000, "b": 900}, 1010, 800, 900),  # b is behind: fuse what both reached
        ({"a": 1000, "b": 900}, 1010, 900, None),  # ... and nothing new until b's next frame
        ({"a": 1000, "b": 900}, 1015, 900, None),  # b's next frame is due at 1000: 15 ms late is within jitter
        ({"a": 1000, "b": 900}, 1030, 900, 1000),  # 30 ms late with nothing measured late before: not waited for
        ({"a": 1000}, 1010, 0, 1000),  # the first fusion
        ({}, 1010, 0, None),  # nobody: nothing to fuse
        ({"a": 2000, "b": 1990}, 1500, 0, 1500),  # frames stamped ahead of the clock: never past now
    ],
)
def test_the_watermark(newest_ms: dict[str, int], now_ms: int, last_ms: int, want_ms: int | None) -> None:
    sch = _scheduler({s: _at(t) for s, t in newest_ms.items()})
    got = sch.instant(list(newest_ms), now_ms * MS, last_ms * MS)
    assert got == (None if want_ms is None else want_ms * MS)


@pytest.mark.parametrize(
    ("delay_ms", "now_ms", "want_ms"),
    [
        (100.0, 1140, None),  # b's frames come 100 ms late: it is waited for 1.5 x that past its expected frame
        (100.0, 1160, 1000),  # ... and not beyond
        (500.0, 1190, None),  # a sensor 500 ms behind is waited for at most max_wait (200 ms) past its frame
        (500.0, 1210, 1000),
    ],
)
def test_each_sensor_is_waited_for_as_long_as_its_recent_frames_predict(
    delay_ms: float, now_ms: int, want_ms: int | None
) -> None:
    sch = _scheduler({"a": _at(1000), "b": _at(900, delay_ms)})
    got = sch.instant(["a", "b"], now_ms * MS, 900 * MS)
    assert got == (None if want_ms is None else want_ms * MS)


def test_a_sensor_not_yet_measured_is_waited_for_the_longest() -> None:
    a = FrameTiming(declared_period_ns=PERIOD)
    for k in range(1, WARMUP_FRAMES):
        a.arrived("accepted", k * PERIOD, k * PERIOD + 1 * MS, 0, WAIT)
    assert a.allowance_ns(WAIT) == WAIT
    a.arrived("accepted", WARMUP_FRAMES * PERIOD, WARMUP_FRAMES * PERIOD + 1 * MS, 0, WAIT)
    assert a.allowance_ns(WAIT) == MIN_ALLOWANCE_NS  # measured now: frames 1 ms after capture


def test_measured_timing_follows_the_frames() -> None:
    a = FrameTiming()
    for k in range(1, 60):  # 30 fps frames, delivered 12 ms after capture, +-2 ms
        stamp = k * 33 * MS
        a.arrived("accepted", stamp, stamp + (12 + (2 if k % 2 else -2)) * MS, 3 * MS, WAIT)
    assert a.period() == pytest.approx(33 * MS, rel=0.01)
    assert a.delay_ns == pytest.approx(12 * MS, abs=2 * MS)
    assert 0 < a.delay_dev_ns <= 2 * MS
    assert a.allowance_ns(WAIT) >= MIN_ALLOWANCE_NS
    # a frame dropped between (a 66 ms step) is not a slower camera
    a.arrived("accepted", 61 * 33 * MS, 61 * 33 * MS + 12 * MS, 3 * MS, WAIT)
    assert a.period() == pytest.approx(33 * MS, rel=0.01)
    # a clock step forgets what the old stamps said
    a.arrived("clock_step", 10 * 33 * MS, 61 * 33 * MS + 50 * MS, 3 * MS, WAIT)
    assert a.frames == 1 and a.newest_ns == 10 * 33 * MS


def test_the_rate_is_capped() -> None:
    sch = _scheduler({"a": _at(1030)}, min_interval_ns=50 * MS)
    assert sch.instant(["a"], 1031 * MS, 1000 * MS) is None  # 30 ms after the last: wait
    sch.sensors["a"] = _at(1060)
    assert sch.instant(["a"], 1061 * MS, 1000 * MS) == 1060 * MS


def test_fixed_mode_fuses_a_fixed_delay_behind_the_clock() -> None:
    sch = _scheduler({"a": _at(1000), "b": _at(1000)}, mode="fixed", min_interval_ns=100 * MS)
    assert sch.instant(["a", "b"], 1005 * MS, 0) == 805 * MS  # now - 200 ms, though every frame is there
    assert sch.instant(["a", "b"], 1050 * MS, 805 * MS) is None  # at most rate_hz
    assert sch.until_due_ns(["a", "b"], 1050 * MS, 805 * MS) == 55 * MS
    assert sch.instant(["a", "b"], 1105 * MS, 805 * MS) == 905 * MS
    lat = sch.last
    assert lat is not None and lat.wait_ns == 200 * MS  # the frames of 905 came at once, then waited 200 ms


def test_until_due_is_the_next_deadline() -> None:
    sch = _scheduler({"a": _at(1000), "b": _at(900)})
    assert sch.until_due_ns(["a", "b"], 1005 * MS, 900 * MS) == 15 * MS  # b's deadline: 900 + 100 + 20
    # everyone past their deadline: only a new frame can make an instant due
    assert sch.until_due_ns(["a", "b"], 1200 * MS, 900 * MS) is None
    assert sch.until_due_ns([], 1005 * MS, 900 * MS) is None


def _info(sid: str) -> SensorInfo:
    model = PanoramicModel(width_px=1080, height_px=162, f_v_px=256.0, v0_px=93.0)
    return SensorInfo(sensor_id=sid, seq=0, stamp_ns=T0, kind="panoramic", model=model, fps=10.0)


def _frame(sid: str, seq: int, t_ms: int) -> Features:
    return Features(sensor_id=sid, seq=seq, stamp_ns=T0 + t_ms * MS, frame_index=seq)


def _fusion() -> Fusion:
    fusion = Fusion(ManagerConfig(manager=ManagerSection(id="m1", rate_hz=100.0, latency_ms=200.0)))
    fusion.absorb(Batch(infos=[_info("a"), _info("b")]))
    return fusion


def _drive(fusion: Fusion, arrivals: list[tuple[int, Features]]) -> list[tuple[int, int]]:
    """Deliver each frame at its arrival time (ms after T0; frames arriving together in one batch, as the shell
    drains them), waking in between at the deadlines the live shell sleeps until; return (instant, when it was
    fused) of every fusion, in ms after T0."""
    fused: list[tuple[int, int]] = []

    def fuse_at(now_ns: int) -> None:
        t = fusion.next_instant(now_ns)
        if t is not None:
            fusion.step(t)
            fused.append(((t - T0) // MS, (now_ns - T0) // MS))

    now = T0
    batches: dict[int, list[Features]] = {}
    for arrival_ms, frame in arrivals:
        batches.setdefault(arrival_ms, []).append(frame)
    for arrival_ms, frames in sorted(batches.items()):
        at = T0 + arrival_ms * MS
        for _ in range(100):
            due = fusion.until_due_ns(now)
            if due is None or now + due >= at:
                break
            now += due
            fuse_at(now)
        now = at
        fusion.absorb(Batch(features=frames, received_ns=now))
        fuse_at(now)
    return fused


def _on_time(sid: str, ks: range) -> list[tuple[int, Features]]:
    """Frames every 100 ms, each arriving 5 ms after capture."""
    return [(100 * k + 5, _frame(sid, k, 100 * k)) for k in ks]


def test_a_sensor_that_stops_holds_the_others_back_only_until_its_deadline() -> None:
    fusion = _fusion()
    fused = _drive(fusion, _on_time("a", range(1, 21)) + _on_time("b", range(1, 11)))  # b stops after 1.0 s
    assert [t for t, _ in fused] == [100 * k for k in range(1, 21)]  # every instant once, with b then without it
    waited = {t: at - t for t, at in fused}
    assert max(waited.values()) == waited[1100] <= 5 + MIN_ALLOWANCE_NS // MS  # b's deadline held 1100 back only
    assert fusion.schedule.sensors["b"].missed == 1  # one deadline missed, counted once however long b stays away


def test_a_frame_300_ms_late_is_dropped_once_its_instant_is_fused_and_never_rewinds() -> None:
    """b's frame of 1100 ms arrives 300 ms late, at 1400 ms. b's frames came on time until then, so the manager
    stops waiting for it just past its expected time and fuses a alone; the late frame's instant is then behind:
    it is counted and dropped, and b's next frames are used again."""
    fusion = _fusion()
    frames = _on_time("a", range(1, 21)) + _on_time("b", range(1, 11)) + [(1400, _frame("b", 11, 1100))]
    fused = _drive(fusion, frames + _on_time("b", range(15, 21)))
    assert [t for t, _ in fused] == [100 * k for k in range(1, 21)]  # every instant once, in order
    assert max(at - t for t, at in fused) <= 5 + MIN_ALLOWANCE_NS // MS  # none held back by the late frame
    assert fusion.schedule.sensors["b"].late == 1  # its instant was fused: counted, dropped
    assert fusion.sensors.counters.late == 1
    assert fusion.step(T0 + 1300 * MS).skipped  # never rewinds


def test_a_sensor_always_300_ms_late_never_holds_the_others_back() -> None:
    """Every one of b's frames arrives 300 ms after capture (beyond the 200 ms most any sensor is waited for):
    after the one wait for its first frame, the others are fused at their own pace, b's frames are counted late,
    and its lateness is measured."""
    fusion = _fusion()
    late = [(100 * k + 300, _frame("b", k, 100 * k)) for k in range(1, 31)]
    fused = _drive(fusion, _on_time("a", range(1, 31)) + late)
    assert fused[0] == (300, 305)  # b's first frame was waited for 200 ms from a's (at 105), then not again
    assert [t for t, _ in fused] == [100 * k for k in range(3, 31)]
    assert max(at - t for t, at in fused) <= 5  # fused as a's frames came
    b = fusion.schedule.sensors["b"]
    assert b.delay_ns == pytest.approx(300 * MS, abs=1 * MS)
    assert b.late >= 25


def test_the_first_frames_of_a_site_arriving_one_by_one_are_fused_together() -> None:
    """The cameras' first frames (one instant) reach the manager a few ms apart: the instant waits for every
    declared camera's, rather than being fused with the first camera alone and the others' dropped as late."""
    fusion = _fusion()
    fused = _drive(fusion, [(105, _frame("a", 1, 100)), (140, _frame("b", 1, 100)), *_on_time("a", range(2, 5))])
    assert fused[0] == (100, 140)
    assert fusion.schedule.sensors["b"].late == 0 and fusion.schedule.sensors["a"].late == 0


def test_a_declared_sensor_that_never_sends_a_frame_is_waited_for_once() -> None:
    fusion = _fusion()
    fused = _drive(fusion, _on_time("a", range(1, 11)))
    assert fused[0] == (300, 305)  # the first instant a could fuse waited the longest for b (200 ms from 105)
    assert [t for t, _ in fused] == [100 * k for k in range(3, 11)]
    assert max(at - t for t, at in fused[1:]) <= 5  # then a alone, at its own pace


def test_a_sensor_that_is_gone_is_not_waited_for() -> None:
    fusion = _fusion()
    fusion.absorb(Batch(presence={"b": False}))
    fused = _drive(fusion, _on_time("a", range(1, 4)))
    assert fused == [(100, 105), (200, 205), (300, 305)]


def test_out_of_order_frames_are_sorted_and_a_clock_step_restarts_a_sensor() -> None:
    fusion = _fusion()
    fusion.absorb(Batch(features=[_frame("a", 2, 200), _frame("a", 1, 100), _frame("b", 1, 100), _frame("b", 2, 200)]))
    assert fusion.next_instant(T0 + 205 * MS) == T0 + 200 * MS
    assert fusion.sensors.counters.out_of_order == 1
    fusion.step(T0 + 200 * MS)
    # b's clock steps back 2 s (a newer seq, an older stamp): its buffer restarts, a is not held back by it forever.
    fusion.absorb(Batch(features=[_frame("a", 3, 300), _frame("b", 3, -1800)]))
    assert fusion.sensors.counters.clock_steps == 1
    t = fusion.next_instant(T0 + 305 * MS)
    assert t == T0 + 300 * MS  # b's newest is far behind: late, not waited for
    fusion.step(t)
    # b's stepped clock keeps counting from there: its frames are late for the instants already fused, and its
    # measured delay (2 s behind the manager's clock) is bounded, so a stays on its own pace.
    for k in range(4, 8):
        fusion.absorb(Batch(features=[_frame("a", k, 100 * k), _frame("b", k, 100 * k - 2100)]))
        t = fusion.next_instant(T0 + (100 * k + 5) * MS)
        assert t == T0 + 100 * k * MS
        fusion.step(t)
    assert fusion.schedule.sensors["b"].allowance_ns(WAIT) <= WAIT
