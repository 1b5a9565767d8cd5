"""The frame contract: frames, a PTZ head's pose on them, and the pacer of scheduled sources."""

from __future__ import annotations

import dataclasses
import threading

import pytest

from common.errors import SourceError
from common.frames import Frame, Pacer, PtzPose


class FakeClock:
    def __init__(self, t_ns: int = 1_000_000_000) -> None:
        self.t_ns = t_ns

    def __call__(self) -> int:
        return self.t_ns


def test_a_frame_is_immutable_and_carries_a_typed_ptz_pose() -> None:
    fixed = Frame(index=3, stamp_ns=7)
    assert fixed.ptz is None and fixed.image is None and fixed.skipped == 0
    pose = PtzPose(pan_rad=0.5, tilt_rad=-0.1, zoom=2.0)
    assert Frame(index=3, stamp_ns=7, ptz=pose).ptz == pose and not pose.moving
    with pytest.raises(dataclasses.FrozenInstanceError):
        fixed.index = 4  # type: ignore[misc]


def test_pacer_slots_on_the_epoch_and_skips_missed_ones() -> None:
    clock = FakeClock(10_000_000_000)
    go, stop = threading.Event(), threading.Event()
    stop.set()  # wait() returns None if it would have to sleep
    assert Pacer(10.0, clock, epoch_ns=10_000_000_000).wait(stop) == (0, 10_000_000_000, 0)  # due now
    pacer = Pacer(10.0, clock, epoch_ns=9_950_000_000)
    assert pacer.wait(stop) is None  # next slot (10.05 s) is in the future
    clock.t_ns = 10_050_000_000
    assert pacer.wait(go) == (1, 10_050_000_000, 0)  # frames stamp their slot, on the epoch grid
    clock.t_ns = 10_550_000_000  # the caller was slow: slots 2..5 passed
    assert pacer.wait(go) == (6, 10_550_000_000, 4)
    with pytest.raises(SourceError):
        Pacer(0.0, clock, 0)
