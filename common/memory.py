"""Give the memory a flood used back to the system (glibc's allocator), so that it leaves no residue.

A flood of large messages (256-blob Features, ~200 KB each, hundreds a second)
is refused or dropped, and its buffers freed, but glibc keeps freed memory for
reuse: it raises its mmap threshold to the largest block freed (so later large
blocks come from the heap, where freed pages stay mapped) and keeps one arena per
thread. The process's RSS then stays at its flood peak. Two calls prevent that,
in the long-lived hubs (the manager, the router):

* :func:`pin_mmap_threshold` fixes the threshold (``mallopt(M_MMAP_THRESHOLD)``;
  pinning it also stops glibc raising it): a block above it is its own mapping,
  unmapped when freed;
* :class:`Trimmer` calls ``malloc_trim(0)`` (free pages of every arena back to the
  kernel) at most every ``period_s``, from the owner's loop.

Both are no-ops where the C library is not glibc.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import logging
import time
from typing import Any

__all__ = ["MMAP_THRESHOLD_BYTES", "Trimmer", "pin_mmap_threshold", "trim"]

logger = logging.getLogger(__name__)

MMAP_THRESHOLD_BYTES = 128 * 1024
"""glibc's own starting threshold: blocks this large or larger get a mapping of their own."""
_M_MMAP_THRESHOLD = -3
"""mallopt parameter number (malloc.h)."""


def _libc() -> Any | None:
    name = ctypes.util.find_library("c")
    try:
        lib = ctypes.CDLL(name or "libc.so.6")
        lib.malloc_trim.argtypes = [ctypes.c_size_t]
        lib.mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    except (OSError, AttributeError):  # not glibc: nothing to tune
        return None
    return lib


_LIBC = _libc()


def pin_mmap_threshold(nbytes: int = MMAP_THRESHOLD_BYTES) -> bool:
    """Blocks of ``nbytes`` or more are mapped on their own and returned when freed; False where not glibc."""
    if _LIBC is None:
        return False
    return bool(_LIBC.mallopt(_M_MMAP_THRESHOLD, int(nbytes)))


def trim() -> bool:
    """Return free heap pages of every arena to the kernel; True if some were (False where not glibc)."""
    if _LIBC is None:
        return False
    return bool(_LIBC.malloc_trim(0))


class Trimmer:
    """Calls :func:`trim` at most every ``period_s`` (each call walks the heap: a few ms for a large one)."""

    def __init__(self, period_s: float = 2.0) -> None:
        self.period_s = period_s
        self._next = time.monotonic() + period_s

    def tick(self) -> None:
        now = time.monotonic()
        if now >= self._next:
            self._next = now + self.period_s
            trim()
