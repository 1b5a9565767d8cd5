"""Republish a recording's raw samples on their zenoh keys with the original timing.

The schedule is computed against ``time.monotonic()`` from the start (sample
``i`` goes out at ``start + (log_i - log_0) / speed``) rather than by sleeping
between samples, so errors never accumulate (docs/zenoh.md §7.1).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from common.errors import ConfigError
from common.session import MSGPACK
from user_agent.recording import iter_raw

__all__ = ["replay"]

logger = logging.getLogger(__name__)


def replay(
    session: Any,
    path: str | Path,
    *,
    speed: float = 1.0,
    should_stop: Callable[[], bool] = lambda: False,
    sleep: Callable[[float], Any] = time.sleep,
    monotonic: Callable[[], float] = time.monotonic,
) -> int:
    """Republish every raw sample of ``path``; returns how many were sent.

    Args:
        session: an open zenoh session.
        speed: playback rate (2.0 = twice as fast); must be > 0.
        should_stop: polled between samples; True ends the replay early.
        sleep: how to wait (tests may pass a fake).
        monotonic: the clock the schedule is kept on, in seconds (tests pass a fake that ``sleep`` advances, so the
            schedule does not depend on how busy the machine is).

    Raises:
        ConfigError: bad speed, or the file is not a recording.
    """
    if not speed > 0:
        raise ConfigError(f"--speed must be > 0, got {speed}")
    import zenoh

    sent = 0
    log0: int | None = None
    wall0 = 0.0
    lateness_max_s = 0.0
    for s in iter_raw(path):
        if should_stop():
            break
        if log0 is None:
            log0, wall0 = s.log_time_ns, monotonic()
        due = wall0 + (s.log_time_ns - log0) / 1e9 / speed
        delay = due - monotonic()
        if delay > 0:
            sleep(delay)
        else:
            lateness_max_s = max(lateness_max_s, -delay)
        session.put(s.key, s.data, encoding=MSGPACK, congestion_control=zenoh.CongestionControl.BLOCK)
        sent += 1
    logger.info("replayed %d samples (worst lateness %.1f ms)", sent, lateness_max_s * 1e3)
    return sent
