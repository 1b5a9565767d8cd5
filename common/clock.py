"""An NTP-corrected wall clock, and interpolation helpers for time alignment.

Protocol (SNTP, RFC 4330, via ``ntplib``): each request yields the server
offset ``θ = ((t1 − t0) + (t2 − t3)) / 2`` and the round-trip delay
``δ = (t3 − t0) − (t2 − t1)``, with t0/t3 the local send/receive times and
t1/t2 the server's receive/send times. Of ``samples`` requests the one with
the smallest delay wins (the NTP clock-filter idea: the shortest round trip
has the least room for path asymmetry, docs/zenoh.md §8.1). Its offset is
then added to ``time.time_ns()`` until the next re-sync, which a background
thread runs every ``resync_s`` seconds.

Uncertainty: the true offset lies within ``δ/2`` of the estimate whatever the
path asymmetry, plus the server's own distance to its reference
(``root_delay/2 + root_dispersion``), plus a frequency tolerance of
:data:`DRIFT_PPM` times the time since the last sync.

With no server configured (``server=""``) the clock is the system clock and
its status says ``source="system"``, so every node can report how its stamps
were made. If the server cannot be reached the clock keeps the last good
offset (or the system clock, source ``"system"``) and keeps retrying.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from dataclasses import dataclass
from typing import Annotated, Literal

import msgspec

from common.config import ConfigStruct

__all__ = ["DRIFT_PPM", "ClockSettings", "ClockStatus", "NtpClock", "interp_linear"]

NTP_LEAP_UNSYNCHRONISED = 3
"""An NTP reply's leap indicator 3: the server's own clock is not synchronised (RFC 5905)."""

logger = logging.getLogger(__name__)

DRIFT_PPM = 15.0
"""Assumed worst-case frequency error of the local oscillator between syncs (parts per million)."""

ClockSource = Literal["ntp", "system"]


class ClockSettings(ConfigStruct, frozen=True):
    """The ``[clock]`` table of a process config."""

    ntp_server: str = ""
    """Host name or address of the NTP server; "" uses the system clock as is."""
    ntp_port: Annotated[int, msgspec.Meta(ge=1, le=65535)] = 123
    samples: Annotated[int, msgspec.Meta(ge=1, le=64)] = 8
    """Requests per sync; more samples raise the chance of a short, symmetric round trip."""
    resync_s: Annotated[float, msgspec.Meta(gt=0.0, le=86_400.0)] = 64.0
    """Seconds between background re-syncs; lower tracks drift better at the cost of traffic."""


@dataclass(frozen=True, slots=True)
class ClockStatus:
    """The clock's current correction, for status messages."""

    offset_ns: int
    """Added to the system clock: server time − system time."""
    uncertainty_ns: int
    """Bound on the error of ``now_ns()`` right now (0 for the system clock: unknown, not zero error)."""
    source: ClockSource
    """"ntp" once a sync succeeded, else "system"."""
    last_sync_ns: int
    """System time of the last successful sync (0: never)."""
    server: str
    """``host:port`` of the NTP server, "" when none is configured."""


@dataclass(frozen=True, slots=True)
class _Sample:
    offset_ns: int
    delay_ns: int
    root_ns: int
    """Server's own synchronisation distance: root_delay/2 + root_dispersion."""


class NtpClock:
    """System time corrected by the offset measured against an NTP server.

    Args:
        server: NTP server host; "" means the system clock, uncorrected.
        port: its UDP port.
        samples: requests per sync; the minimum-delay one is kept.
        resync_s: seconds between background re-syncs.
        timeout_s: per-request timeout.
    """

    def __init__(
        self, server: str = "", port: int = 123, samples: int = 8, resync_s: float = 64.0, timeout_s: float = 1.0
    ) -> None:
        if samples < 1:
            raise ValueError(f"samples must be >= 1, got {samples}")
        if resync_s <= 0:
            raise ValueError(f"resync_s must be > 0, got {resync_s}")
        self.server = server
        self.port = port
        self.samples = samples
        self.resync_s = resync_s
        self.timeout_s = timeout_s
        self._lock = threading.Lock()
        self._offset_ns = 0
        self._base_uncertainty_ns = 0
        self._last_sync_ns = 0
        self._synced = False
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    @classmethod
    def from_settings(cls, settings: ClockSettings, timeout_s: float = 1.0) -> NtpClock:
        """Build a clock from the ``[clock]`` config table."""
        return cls(
            server=settings.ntp_server,
            port=settings.ntp_port,
            samples=settings.samples,
            resync_s=settings.resync_s,
            timeout_s=timeout_s,
        )

    # -- lifecycle ------------------------------------------------------------
    def start(self) -> None:
        """Sync once now (blocking, bounded by ``samples × timeout_s``), then re-sync in the background."""
        if not self.server or self._thread is not None:
            return
        if not self.sync():
            logger.warning(
                "NTP server %s unreachable: using the system clock until a sync succeeds", self._server_text()
            )
        self._stop.clear()
        self._thread = threading.Thread(target=self._loop, name="ntp-clock", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Stop the background re-sync (the last offset stays in use)."""
        self._stop.set()
        thread, self._thread = self._thread, None
        if thread is not None:
            thread.join(timeout=self.samples * self.timeout_s + 1.0)

    def __enter__(self) -> NtpClock:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def _loop(self) -> None:
        while not self._stop.wait(self.resync_s):
            self.sync(background=True)

    # -- measurement ----------------------------------------------------------
    def _request(self) -> _Sample | None:
        import ntplib

        try:
            stats = ntplib.NTPClient().request(self.server, version=4, port=self.port, timeout=self.timeout_s)
        except (ntplib.NTPException, OSError) as err:
            logger.debug("NTP request to %s failed: %s", self._server_text(), err)
            return None
        offset_s, delay_s = float(stats.offset), float(stats.delay)
        if not (math.isfinite(offset_s) and math.isfinite(delay_s)) or stats.leap == NTP_LEAP_UNSYNCHRONISED:
            logger.debug("NTP reply from %s unusable (leap=%s)", self._server_text(), stats.leap)
            return None
        root_s = float(stats.root_delay) / 2.0 + float(stats.root_dispersion)
        return _Sample(
            offset_ns=round(offset_s * 1e9), delay_ns=max(0, round(delay_s * 1e9)), root_ns=max(0, round(root_s * 1e9))
        )

    def sync(self, *, background: bool = False) -> bool:
        """Measure the offset now; keep the minimum-delay sample. Returns False if no reply came. ``background``:
        the re-sync thread's, which stops between two requests once :meth:`stop` is asked (a server that stopped
        answering costs a stop one request's timeout, not every sample's)."""
        if not self.server:
            return False
        best: _Sample | None = None
        for _ in range(self.samples):
            if background and self._stop.is_set():
                break
            sample = self._request()
            if sample is not None and (best is None or sample.delay_ns < best.delay_ns):
                best = sample
        if best is None:
            logger.warning("no reply from NTP server %s", self._server_text())
            return False
        with self._lock:
            self._offset_ns = best.offset_ns
            self._base_uncertainty_ns = best.delay_ns // 2 + best.root_ns
            self._last_sync_ns = time.time_ns()
            self._synced = True
        logger.info(
            "clock synced to %s: offset %+.3f ms, delay %.3f ms",
            self._server_text(),
            best.offset_ns / 1e6,
            best.delay_ns / 1e6,
        )
        return True

    # -- reading --------------------------------------------------------------
    def now_ns(self) -> int:
        """Current time in Unix epoch ns on the corrected clock."""
        with self._lock:
            offset = self._offset_ns
        return time.time_ns() + offset

    def status(self) -> ClockStatus:
        """The correction in use and how far it can be trusted now."""
        with self._lock:
            synced, offset, base, last = self._synced, self._offset_ns, self._base_uncertainty_ns, self._last_sync_ns
        if not synced:
            return ClockStatus(0, 0, "system", 0, self._server_text())
        drift_ns = round(max(0, time.time_ns() - last) * DRIFT_PPM * 1e-6)
        return ClockStatus(offset, base + drift_ns, "ntp", last, self._server_text())

    def _server_text(self) -> str:
        return f"{self.server}:{self.port}" if self.server else ""


# ---------------------------------------------------------------------------
# Interpolation (docs/zenoh.md §8.3 (b): align observations to a fusion time)
# ---------------------------------------------------------------------------


def interp_linear(t0: float, v0: float, t1: float, v1: float, t: float) -> float:
    """Value at ``t`` on the line through (t0, v0) and (t1, v1).

    Extrapolates outside [t0, t1]; callers bound how far. With ``t0 == t1``
    the newer value ``v1`` is returned. Times may be ns ints or seconds.
    """
    if t1 == t0:
        return v1
    return v0 + (v1 - v0) * ((t - t0) / (t1 - t0))
