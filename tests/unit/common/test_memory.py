"""Giving freed memory back: a large buffer freed leaves no residue in the process's RSS (glibc)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from common.memory import Trimmer, pin_mmap_threshold, trim


def _rss_mb() -> float:
    m = re.search(r"^VmRSS:\s+(\d+) kB", Path("/proc/self/status").read_text(), re.M)
    assert m is not None
    return int(m.group(1)) / 1024


@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="needs /proc")
def test_a_flood_of_large_buffers_freed_goes_back_to_the_system() -> None:
    if not pin_mmap_threshold():
        pytest.skip("not glibc: nothing to pin")
    del_one = b"\x01" * 200_000
    del del_one  # unpinned, glibc would now raise its mmap threshold past 200 KB: the flood below on its heap
    before = _rss_mb()
    # 300 MB in 200 KB buffers (a 256-blob Features each), interleaved with small objects that pin heap pages.
    held = [(b"\x01" * 200_000, [0.5] * 20) for _ in range(1500)]
    assert _rss_mb() > before + 200
    del held
    trim()
    assert _rss_mb() < before + 30


def test_the_trimmer_trims_at_most_once_a_period() -> None:
    t = Trimmer(period_s=3600.0)
    nxt = t._next
    t.tick()
    assert t._next == nxt  # not due yet: nothing done
