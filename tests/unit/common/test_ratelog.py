"""Rate-limited logging: one line per sender per period, the rest counted and said."""

from __future__ import annotations

import logging

import pytest

from common.ratelog import SenderLog


class _Clock:
    def __init__(self) -> None:
        self.now_s = 0.0

    def __call__(self) -> float:
        return self.now_s


def test_a_flooding_sender_gets_one_line_a_second_with_the_count(caplog: pytest.LogCaptureFixture) -> None:
    clock = _Clock()
    log = SenderLog(logging.getLogger("t.ratelog"), period_s=1.0, clock=clock)
    with caplog.at_level(logging.INFO, logger="t.ratelog"):
        for i in range(5000):  # 5 s of 1000 requests a second from mallory, and one from alice
            clock.now_s = i / 1000
            log.log(logging.INFO, "mallory", "PTZ acquire by %s: %d", "mallory", i)
        log.log(logging.INFO, "alice", "PTZ acquire by %s: %d", "alice", 0)
        clock.now_s = 6.0
        log.flush()
    lines = [r.getMessage() for r in caplog.records]
    assert len(lines) == 5 + 1 + 1  # one a second, alice's own, and the last second's count
    assert lines[0] == "PTZ acquire by mallory: 0"
    assert lines[1].startswith("PTZ acquire by mallory: 1000 (999 more from mallory")
    assert "PTZ acquire by alice: 0" in lines
    assert lines[-1].startswith("999 more lines from mallory")


def test_fresh_sender_ids_cannot_grow_it(caplog: pytest.LogCaptureFixture) -> None:
    log = SenderLog(logging.getLogger("t.ratelog2"), max_senders=4, clock=_Clock())
    with caplog.at_level(logging.INFO, logger="t.ratelog2"):
        for i in range(1000):
            log.log(logging.INFO, f"f{i}", "from %s", f"f{i}")
    assert len(caplog.records) == 5  # four named senders, then one line for all the others
    assert len(log._senders) == 5
