"""NtpClock against a fake NTP responder (2 s ahead) and a real chronyd; interpolation helpers."""

from __future__ import annotations

import contextlib
import os
import pwd
import shutil
import signal
import socket
import subprocess
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import ntplib
import pytest

from common.clock import ClockSettings, NtpClock, interp_linear
from common.config import parse_config
from common.errors import ConfigError
from tests.support import REPO, FakeNtpServer, free_port, skip_or_fail, wait_for

SKEW_S = 2.0
TOLERANCE_NS = 5_000_000  # 5 ms: the acceptance bound


def test_system_clock_without_server() -> None:
    clock = NtpClock()
    clock.start()
    before = time.time_ns()
    now = clock.now_ns()
    after = time.time_ns()
    clock.stop()
    assert before <= now <= after
    st = clock.status()
    assert (st.source, st.offset_ns, st.server, st.last_sync_ns) == ("system", 0, "", 0)


def test_corrected_clock_agrees_with_skewed_server() -> None:
    with FakeNtpServer(skew_s=SKEW_S) as server:
        clock = NtpClock("127.0.0.1", server.port, samples=8, resync_s=60.0, timeout_s=1.0)
        clock.start()
        try:
            ours = clock.now_ns()
            theirs = round(server.now_s() * 1e9)
            st = clock.status()
        finally:
            clock.stop()
    assert abs(ours - theirs) < TOLERANCE_NS, f"corrected clock off by {(ours - theirs) / 1e6:.3f} ms"
    assert st.source == "ntp"
    assert abs(st.offset_ns - SKEW_S * 1e9) < TOLERANCE_NS
    assert 0 < st.uncertainty_ns < TOLERANCE_NS
    assert st.server == f"127.0.0.1:{server.port}"
    assert st.last_sync_ns > 0
    assert server.requests == 8


def test_background_resync_follows_a_clock_step() -> None:
    with FakeNtpServer(skew_s=SKEW_S) as server:
        clock = NtpClock("127.0.0.1", server.port, samples=2, resync_s=0.1, timeout_s=1.0)
        with clock:
            first = clock.status().last_sync_ns
            server.skew_s = -1.0  # the server's clock steps back 3 s
            wait_for(lambda: abs(clock.status().offset_ns + 1e9) < TOLERANCE_NS, 5.0, "re-sync to the stepped clock")
            assert clock.status().last_sync_ns > first


def test_unreachable_server_falls_back_to_system_clock() -> None:
    port = free_port()  # nothing answers there
    clock = NtpClock("127.0.0.1", port, samples=2, resync_s=60.0, timeout_s=0.1)
    clock.start()
    try:
        st = clock.status()
        assert abs(clock.now_ns() - time.time_ns()) < 50_000_000
    finally:
        clock.stop()
    assert st.source == "system"
    assert st.offset_ns == 0
    assert st.server == f"127.0.0.1:{port}"


def test_uncertainty_grows_with_time_since_sync() -> None:
    with FakeNtpServer(skew_s=0.5) as server:
        clock = NtpClock("127.0.0.1", server.port, samples=1, resync_s=60.0)
        clock.start()
        clock.stop()
        u0 = clock.status().uncertainty_ns
        time.sleep(0.05)
        assert clock.status().uncertainty_ns > u0


def test_settings_table_and_from_settings() -> None:
    s = parse_config({"ntp_server": "ntp.local", "ntp_port": 1123, "samples": 4}, ClockSettings, "node.toml")
    clock = NtpClock.from_settings(s)
    assert (clock.server, clock.port, clock.samples, clock.resync_s) == ("ntp.local", 1123, 4, 64.0)
    assert ClockSettings() == ClockSettings(ntp_server="", ntp_port=123, samples=8, resync_s=64.0)
    with pytest.raises(ConfigError, match=r"node.toml: ntp_port"):
        parse_config({"ntp_port": 0}, ClockSettings, "node.toml")
    with pytest.raises(ConfigError, match=r"unknown key 'server'"):
        parse_config({"server": "x"}, ClockSettings, "node.toml")


@pytest.mark.parametrize("bad", [{"samples": 0}, {"resync_s": 0.0}])
def test_bad_constructor_arguments(bad: dict[str, float]) -> None:
    with pytest.raises(ValueError):
        NtpClock("127.0.0.1", **bad)  # type: ignore[arg-type]


# -- interpolation -----------------------------------------------------------


@pytest.mark.parametrize(
    ("t0", "v0", "t1", "v1", "t", "want"),
    [
        (0, 0.0, 10, 10.0, 5, 5.0),
        (0, 0.0, 10, 10.0, 0, 0.0),
        (0, 0.0, 10, 10.0, 10, 10.0),
        (0, 0.0, 10, 10.0, 15, 15.0),  # extrapolation
        (1_000_000_000, 2.0, 2_000_000_000, 4.0, 1_250_000_000, 2.5),  # ns stamps
        (3, 1.0, 3, 7.0, 3, 7.0),  # equal times: the newer value
    ],
)
def test_interp_linear(t0: float, v0: float, t1: float, v1: float, t: float, want: float) -> None:
    assert interp_linear(t0, v0, t1, v1, t) == pytest.approx(want)


# -- a real NTP server: Debian's chronyd, unprivileged on a loopback port ----


def _find_chronyd() -> str | None:
    found = shutil.which("chronyd") or shutil.which("chronyd", path="/usr/sbin:/sbin")
    if found:
        return found
    local = REPO / ".venv" / "sys" / "usr" / "sbin" / "chronyd"
    return str(local) if local.is_file() and os.access(local, os.X_OK) else None


@pytest.fixture
def chronyd(tmp_path: Path) -> Iterator[int]:
    """Start chronyd serving NTP on 127.0.0.1:<free port>; yield the port."""
    exe = _find_chronyd()
    if exe is None:
        skip_or_fail("chronyd not found on PATH or in .venv/sys (run tests/system_deps.sh as root)")
        return
    port = free_port(kind=socket.SOCK_DGRAM)
    conf = tmp_path / "chrony.conf"
    conf.write_text(
        f"port {port}\nbindaddress 127.0.0.1\nallow 127.0.0.1\nlocal stratum 8\ncmdport 0\n"
        f"pidfile {tmp_path}/chronyd.pid\ndriftfile {tmp_path}/drift\n"
    )
    tmp_path.chmod(0o777)
    # -U: no root check; -x: never touch the system clock; -d: foreground. -u: the user to run as (root drops
    # to nobody; anyone else stays themselves), else chronyd looks for the Debian user _chrony.
    user = "nobody" if os.geteuid() == 0 else pwd.getpwuid(os.geteuid()).pw_name
    args = [exe, "-U", "-u", user, "-d", "-x", "-f", str(conf)]
    log = (tmp_path / "chronyd.log").open("wb")
    proc = subprocess.Popen(args, stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
    client = ntplib.NTPClient()

    def answers() -> bool:
        if proc.poll() is not None:
            raise AssertionError(f"chronyd exited with {proc.returncode}: {(tmp_path / 'chronyd.log').read_text()}")
        try:
            client.request("127.0.0.1", version=4, port=port, timeout=0.2)
        except (ntplib.NTPException, OSError):
            return False
        return True

    try:
        wait_for(answers, 10.0, "chronyd to answer NTP requests")
        yield port
    finally:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(5.0)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(5.0)
        log.close()


def test_against_real_chronyd(chronyd: int) -> None:
    clock = NtpClock("127.0.0.1", chronyd, samples=4, resync_s=60.0, timeout_s=1.0)
    clock.start()
    try:
        st = clock.status()
        diff_ns = clock.now_ns() - time.time_ns()
    finally:
        clock.stop()
    # chronyd serves this host's own clock: the measured offset is ~0 and small against its uncertainty.
    assert st.source == "ntp"
    assert abs(st.offset_ns) < TOLERANCE_NS
    assert abs(diff_ns) < TOLERANCE_NS
    assert st.uncertainty_ns < TOLERANCE_NS


def test_stop_ends_a_background_resync_whose_server_went_silent() -> None:
    """Once the server stops answering, a stop asked while the background re-sync waits on it ends that re-sync
    after the request in flight: the remaining samples are not sent (each would wait out its timeout)."""
    silent = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    silent.bind(("127.0.0.1", 0))
    silent.settimeout(0.05)
    heard = [0]
    done = False

    def listen() -> None:
        while not done:
            try:
                silent.recvfrom(512)
                heard[0] += 1
            except TimeoutError:
                continue

    listener = threading.Thread(target=listen, daemon=True)
    listener.start()
    samples = 6
    clock = NtpClock("127.0.0.1", silent.getsockname()[1], samples=samples, resync_s=0.05, timeout_s=0.2)
    try:
        clock.start()  # the first sync asks every sample, blocking: nobody answers
        wait_for(lambda: heard[0] >= samples + 1, 10.0, "the background re-sync's first request")
        asked = heard[0]
        clock.stop()  # joins the re-sync thread: whatever it sent is in the socket by now
        done = True
        listener.join(timeout=2.0)
        silent.setblocking(False)
        with contextlib.suppress(BlockingIOError):
            while True:
                silent.recvfrom(512)
                heard[0] += 1
        assert heard[0] - asked <= 1, f"{heard[0] - asked} requests after the stop was asked"
    finally:
        done = True
        silent.close()
