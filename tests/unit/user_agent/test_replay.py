"""Replaying a recording: every raw sample goes out on its key, in log order, on the recorded schedule."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from common.errors import ConfigError
from user_agent.recording import iter_raw
from user_agent.replay import replay


class _Session:
    """Collects what would be put on zenoh."""

    def __init__(self) -> None:
        self.puts: list[tuple[str, bytes]] = []

    def put(self, key: str, data: bytes, **_options: Any) -> None:
        self.puts.append((key, data))


class _FakeClock:
    """A monotonic clock that only the fake sleep moves."""

    START_S = 100.0

    def __init__(self) -> None:
        self.now_s = self.START_S

    def monotonic(self) -> float:
        return self.now_s

    def sleep(self, seconds: float) -> None:
        assert seconds > 0
        self.now_s += seconds


@pytest.mark.parametrize("speed", [1.0, 4.0])
def test_every_raw_sample_goes_out_in_order_on_the_recorded_schedule(recorded: tuple[Path, Path], speed: float) -> None:
    mcap, _ = recorded
    samples = list(iter_raw(mcap))
    session, clock = _Session(), _FakeClock()
    sent_at: list[float] = []

    def put(key: str, data: bytes, **_options: Any) -> None:
        sent_at.append(clock.now_s - _FakeClock.START_S)
        session.puts.append((key, data))

    session.put = put  # type: ignore[method-assign]
    assert replay(session, mcap, speed=speed, sleep=clock.sleep, monotonic=clock.monotonic) == len(samples) > 100
    assert session.puts == [(s.key, s.data) for s in samples]  # the invalid payload too: it is raw
    # On an injected clock the schedule is exact, however busy the machine: sample i goes out at its offset / speed.
    due = [(s.log_time_ns - samples[0].log_time_ns) / 1e9 / speed for s in samples]
    assert sent_at == pytest.approx(due, abs=1e-9)


def test_a_stop_request_ends_the_replay_early(recorded: tuple[Path, Path]) -> None:
    session = _Session()
    assert replay(session, recorded[0], should_stop=lambda: len(session.puts) >= 5, sleep=lambda _s: None) == 5


@pytest.mark.parametrize("speed", [0.0, -1.0, float("nan")])
def test_a_speed_that_is_not_positive_is_refused(recorded: tuple[Path, Path], speed: float) -> None:
    with pytest.raises(ConfigError, match="--speed"):
        replay(_Session(), recorded[0], speed=speed)


def test_a_file_that_is_not_a_recording_is_refused(tmp_path: Path) -> None:
    bad = tmp_path / "x.mcap"
    bad.write_bytes(b"not an mcap file at all")
    with pytest.raises(ConfigError, match=r"x\.mcap"):
        replay(_Session(), bad, sleep=lambda _s: None)
    with pytest.raises(ConfigError, match="no such recording"):
        replay(_Session(), tmp_path / "missing.mcap")
