"""Logging that a flood cannot turn into a flood of lines: one line per sender per period, with a count.

An agent that sends thousands of PTZ requests a second would otherwise write a
line each (37,591 lines in 30 s, issue 24). :class:`SenderLog` writes the first
line of each sender in each ``period_s``; the lines it held back are counted and
said with the sender's next line, or by :meth:`SenderLog.flush` (call it from
the owner's loop) once the period is over. At most ``max_senders`` senders are
remembered; lines of further ones are counted under ``*``, so a flood of fresh
ids cannot grow memory either.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass

__all__ = ["SenderLog"]

OTHERS = "*"
"""Where the lines of senders beyond ``max_senders`` are counted."""


@dataclass(slots=True)
class _Sender:
    last_s: float
    held: int = 0


class SenderLog:
    """Rate-limited lines per sender (not thread-safe: one owner thread)."""

    def __init__(
        self,
        logger: logging.Logger,
        period_s: float = 1.0,
        max_senders: int = 256,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.logger = logger
        self.period_s = period_s
        self.max_senders = max_senders
        self._clock = clock
        self._senders: dict[str, _Sender] = {}

    def log(self, level: int, sender: str, msg: str, *args: object) -> None:
        """Log ``msg % args`` unless ``sender`` already had a line in the last ``period_s`` (then count it)."""
        now = self._clock()
        if sender not in self._senders and len(self._senders) >= self.max_senders:
            sender = OTHERS
        st = self._senders.get(sender)
        if st is not None and now - st.last_s < self.period_s:
            st.held += 1
            return
        held = st.held if st is not None else 0
        self._senders[sender] = _Sender(now)
        if held:
            self.logger.log(level, msg + " (%d more from %s in the last %.0f s not logged)", *args, held, sender,
                            self.period_s)  # fmt: skip
        else:
            self.logger.log(level, msg, *args)

    def flush(self, level: int = logging.INFO) -> None:
        """Say the held-back counts of senders whose period is over; forget senders quiet for a while."""
        now = self._clock()
        for sender, st in list(self._senders.items()):
            if now - st.last_s < self.period_s:
                continue
            if st.held:
                self.logger.log(level, "%d more lines from %s in the last %.0f s not logged", st.held, sender,
                                self.period_s)  # fmt: skip
                st.held, st.last_s = 0, now
            elif now - st.last_s > 60 * self.period_s:
                del self._senders[sender]
