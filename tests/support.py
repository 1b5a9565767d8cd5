"""Shared test helpers: free ports, managed subprocesses, a real router, readiness waits, an NTP responder.

Every integration test starts real processes on loopback with multicast
scouting off and waits for readiness (an accepting port, a liveliness token,
a first sample) with a deadline, never a bare sleep before an assertion.

Typical use (fixtures from ``tests/conftest.py``)::

    def test_x(router, spawn, tmp_path):
        node = spawn([sys.executable, "-m", "sensor_node", "--config", cfg, "--connect", router.endpoint])
        with client_session(router.endpoint) as s:
            wait_for_liveliness(s, Keys().sensor("pano1"), timeout_s=10)
"""

from __future__ import annotations

import contextlib
import os
import re
import signal
import socket
import struct
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest

__all__ = [
    "CI",
    "REPO",
    "FakeNtpServer",
    "ManagedProcess",
    "RouterProcess",
    "client_session",
    "free_port",
    "in_ci",
    "skip_or_fail",
    "spawn",
    "start_router",
    "wait_for",
    "wait_for_liveliness",
    "wait_for_port",
]

REPO = Path(__file__).resolve().parent.parent
"""The repository root (so tests never depend on the working directory)."""


def in_ci() -> bool:
    """True when running under CI (``CI=true``): nothing may skip for lack of a component."""
    return os.environ.get("CI", "").strip().lower() in {"1", "true", "yes"}


CI = in_ci()


def skip_or_fail(reason: str) -> None:
    """Skip the test locally, fail it under ``CI=true`` (contract: no skips in CI)."""
    if in_ci():
        pytest.fail(f"required component missing under CI=true: {reason}")
    pytest.skip(reason)


# ---------------------------------------------------------------------------
# Ports and waiting
# ---------------------------------------------------------------------------


def free_port(kind: int = socket.SOCK_STREAM) -> int:
    """A loopback port that was free a moment ago (bind to 0, read, close).

    There is a tiny race window before the caller binds it; callers that start
    servers should retry on "address already in use" (``start_router`` does).
    """
    with socket.socket(socket.AF_INET, kind) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def wait_for(pred: Callable[[], Any], timeout_s: float, what: str, poll_s: float = 0.02) -> Any:
    """Poll ``pred`` until it returns something truthy; return that value.

    Raises:
        AssertionError: ``"timed out after {timeout_s} s waiting for {what}"``.
    """
    deadline = time.monotonic() + timeout_s
    while True:
        value = pred()
        if value:
            return value
        if time.monotonic() >= deadline:
            raise AssertionError(f"timed out after {timeout_s:g} s waiting for {what}")
        time.sleep(poll_s)


def port_accepts(port: int, host: str = "127.0.0.1") -> bool:
    """True if a TCP connection to ``host:port`` is accepted now."""
    try:
        with socket.create_connection((host, port), timeout=0.2):
            return True
    except OSError:
        return False


def wait_for_port(port: int, timeout_s: float, host: str = "127.0.0.1", proc: ManagedProcess | None = None) -> None:
    """Wait until ``host:port`` accepts TCP connections; fail early if ``proc`` died."""

    def ready() -> bool:
        if proc is not None and not proc.alive:
            raise AssertionError(
                f"{proc.name} exited with {proc.returncode} before {host}:{port} accepted:\n{proc.log()}"
            )
        return port_accepts(port, host)

    wait_for(ready, timeout_s, f"{host}:{port} to accept connections")


# ---------------------------------------------------------------------------
# Managed subprocesses
# ---------------------------------------------------------------------------


def child_env(extra: dict[str, str] | None = None) -> dict[str, str]:
    """Environment for child processes: unbuffered output, the repo importable, no stray zenoh config."""
    env = dict(os.environ)
    env["PYTHONUNBUFFERED"] = "1"
    env.pop("ZENOH_CONFIG", None)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(REPO), env.get("PYTHONPATH", "")) if p)
    if extra:
        env.update(extra)
    return env


@dataclass
class ManagedProcess:
    """A subprocess with its stdout and stderr captured to files.

    Stop it with :meth:`stop` (SIGTERM, wait, then SIGKILL); read its output
    with :meth:`log`, :meth:`stdout_text`, or wait for a line with
    :meth:`wait_for_output`.
    """

    name: str
    args: list[str]
    popen: subprocess.Popen[bytes]
    stdout_path: Path
    stderr_path: Path

    @property
    def pid(self) -> int:
        return self.popen.pid

    @property
    def alive(self) -> bool:
        return self.popen.poll() is None

    @property
    def returncode(self) -> int | None:
        return self.popen.poll()

    def stdout_text(self) -> str:
        return self.stdout_path.read_text(errors="replace") if self.stdout_path.exists() else ""

    def stderr_text(self) -> str:
        return self.stderr_path.read_text(errors="replace") if self.stderr_path.exists() else ""

    def log(self) -> str:
        """Both streams, labelled, for failure messages."""
        return (
            f"--- {self.name} (pid {self.pid}, rc {self.returncode}): {' '.join(self.args)}\n"
            f"--- stdout:\n{self.stdout_text()}--- stderr:\n{self.stderr_text()}--- end {self.name}\n"
        )

    def wait_for_output(self, pattern: str, timeout_s: float, stream: str = "both") -> re.Match[str]:
        """Wait until ``pattern`` (a regex) appears in the process output; fail early if it exits."""
        rx = re.compile(pattern)

        def found() -> re.Match[str] | None:
            text = {"stdout": self.stdout_text, "stderr": self.stderr_text}.get(
                stream, lambda: self.stdout_text() + self.stderr_text()
            )()
            m = rx.search(text)
            if m is None and not self.alive:
                raise AssertionError(
                    f"{self.name} exited with {self.returncode} before printing {pattern!r}:\n{self.log()}"
                )
            return m

        return wait_for(found, timeout_s, f"{self.name} to print {pattern!r}")

    def signal(self, signum: int) -> None:
        if self.alive:
            os.kill(self.pid, signum)

    def wait(self, timeout_s: float) -> int:
        """Wait for exit; raise AssertionError (with the log) if it does not exit in time."""
        try:
            return self.popen.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired as err:
            raise AssertionError(f"{self.name} did not exit within {timeout_s:g} s:\n{self.log()}") from err

    def stop(self, timeout_s: float = 5.0) -> int:
        """SIGTERM, wait up to ``timeout_s``, then SIGKILL. Returns the exit code (negative: killed by a signal)."""
        if self.alive:
            with contextlib.suppress(ProcessLookupError):
                self.popen.send_signal(signal.SIGTERM)
            try:
                self.popen.wait(timeout=timeout_s)
            except subprocess.TimeoutExpired:
                with contextlib.suppress(ProcessLookupError):
                    self.popen.kill()
                self.popen.wait(timeout=5.0)
        return int(self.popen.returncode)

    def __enter__(self) -> ManagedProcess:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


def spawn(
    args: Sequence[str | os.PathLike[str]],
    env: dict[str, str] | None = None,
    cwd: str | os.PathLike[str] | None = None,
    log_dir: str | os.PathLike[str] | None = None,
    name: str | None = None,
) -> ManagedProcess:
    """Start ``args`` with stdout/stderr going to files in ``log_dir`` (a temp dir by default).

    ``env`` entries are added to a copy of the test's environment (see
    :func:`child_env`). The caller (or the ``spawn`` fixture) must stop it.
    """
    argv = [str(a) for a in args]
    if name:
        label = name
    elif len(argv) >= 3 and argv[1] == "-m":
        label = argv[2]
    else:
        label = Path(argv[0]).name
    directory = Path(log_dir) if log_dir is not None else Path(tempfile.mkdtemp(prefix="panostereo-proc-"))
    directory.mkdir(parents=True, exist_ok=True)
    stem = re.sub(r"[^A-Za-z0-9_.-]", "_", label)
    n = 0
    while (directory / f"{stem}.{n}.out").exists():
        n += 1
    out_path, err_path = directory / f"{stem}.{n}.out", directory / f"{stem}.{n}.err"
    with out_path.open("wb") as out, err_path.open("wb") as err:
        popen = subprocess.Popen(
            argv, stdout=out, stderr=err, stdin=subprocess.DEVNULL, env=child_env(env), cwd=cwd or REPO
        )
    return ManagedProcess(label, argv, popen, out_path, err_path)


# ---------------------------------------------------------------------------
# The router
# ---------------------------------------------------------------------------


@dataclass
class RouterProcess:
    """A running ``panostereo router`` subprocess."""

    proc: ManagedProcess
    port: int
    endpoint: str = field(init=False)

    def __post_init__(self) -> None:
        self.endpoint = f"tcp/127.0.0.1:{self.port}"

    def stop(self, timeout_s: float = 5.0) -> int:
        return self.proc.stop(timeout_s)


def router_command(port: int, *extra: str) -> list[str]:
    """The command line of a loopback router on ``port``."""
    return [sys.executable, "-m", "panostereo", "router", "--listen", f"tcp/127.0.0.1:{port}", *extra]


def start_router(
    port: int | None = None,
    log_dir: str | os.PathLike[str] | None = None,
    timeout_s: float = 15.0,
    attempts: int = 3,
) -> RouterProcess:
    """Start ``panostereo router`` on loopback and wait until it accepts connections.

    With ``port=None`` a free port is chosen, and a lost race for it (another
    process bound it first) is retried with a new port.
    """
    last_log = ""
    for _ in range(attempts if port is None else 1):
        p = free_port() if port is None else port
        proc = spawn(router_command(p), log_dir=log_dir, name=f"router-{p}")
        try:
            wait_for_port(p, timeout_s, proc=proc)
            proc.wait_for_output(r"listening on", timeout_s)
        except AssertionError:
            proc.stop()
            last_log = proc.log()
            if "already in use" in last_log and port is None:
                continue
            raise
        return RouterProcess(proc, p)
    raise AssertionError(f"could not start a router after {attempts} attempts:\n{last_log}")


# ---------------------------------------------------------------------------
# In-test zenoh sessions
# ---------------------------------------------------------------------------


@contextlib.contextmanager
def client_session(endpoint: str, connect_timeout_ms: int = 10_000) -> Iterator[Any]:
    """A zenoh client session connected to ``endpoint``, multicast scouting off; closed on exit."""
    from common.session import SessionSettings, open_session

    settings = SessionSettings(mode="client", connect=[endpoint], connect_timeout_ms=connect_timeout_ms)
    with open_session(settings) as session:
        yield session


def alive_tokens(session: Any, key_expr: str, timeout_s: float = 1.0) -> list[str]:
    """Keys of the liveliness tokens matching ``key_expr`` alive now."""
    return [str(r.ok.key_expr) for r in session.liveliness().get(key_expr, timeout=timeout_s) if r.ok is not None]


def wait_for_liveliness(session: Any, key: str, timeout_s: float) -> list[str]:
    """Wait until a liveliness token matching ``key`` is alive; return the matching keys."""
    return wait_for(lambda: alive_tokens(session, key, timeout_s=0.5), timeout_s, f"liveliness token {key!r}", 0.05)


def wait_for_no_liveliness(session: Any, key: str, timeout_s: float) -> None:
    """Wait until no liveliness token matches ``key``."""
    wait_for(
        lambda: not alive_tokens(session, key, timeout_s=0.5), timeout_s, f"liveliness token {key!r} to vanish", 0.05
    )


# ---------------------------------------------------------------------------
# A tiny NTP responder with a deliberately wrong clock
# ---------------------------------------------------------------------------

_NTP_EPOCH_OFFSET_S = 2_208_988_800
"""Seconds from 1900-01-01 (NTP era 0) to 1970-01-01 (Unix)."""


def _ntp_timestamp(unix_s: float) -> bytes:
    t = unix_s + _NTP_EPOCH_OFFSET_S
    secs = int(t)
    frac = int((t - secs) * (1 << 32)) & 0xFFFFFFFF
    return struct.pack("!II", secs & 0xFFFFFFFF, frac)


class FakeNtpServer:
    """An SNTP server on ``127.0.0.1:<ephemeral>`` whose clock is ``skew_s`` ahead of this host's.

    It answers mode-3 (client) requests with mode-4 replies (RFC 4330):
    originate = the request's transmit timestamp, receive/transmit = its own
    skewed clock, stratum 1, zero root delay/dispersion. Use as a context manager.
    """

    def __init__(self, skew_s: float = 0.0, stratum: int = 1) -> None:
        self.skew_s = skew_s
        self.stratum = stratum
        self.requests = 0
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._sock.bind(("127.0.0.1", 0))
        self._sock.settimeout(0.1)
        self.port = int(self._sock.getsockname()[1])
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, name="fake-ntp", daemon=True)

    def now_s(self) -> float:
        """This server's (skewed) clock, Unix seconds."""
        return time.time() + self.skew_s

    def _serve(self) -> None:
        while not self._stop.is_set():
            try:
                data, addr = self._sock.recvfrom(512)
            except TimeoutError:
                continue
            except OSError:
                return
            recv_s = self.now_s()
            if len(data) < 48 or (data[0] & 0x7) != 3:
                continue
            version = (data[0] >> 3) & 0x7
            reply = (
                bytes([(0 << 6) | (version << 3) | 4, self.stratum, data[2], 0xEC])  # LI=0, VN, mode 4; precision 2^-20
                + struct.pack("!II", 0, 0)  # root delay, root dispersion
                + b"TEST"  # reference id
                + _ntp_timestamp(recv_s)  # reference timestamp
                + data[40:48]  # originate = client's transmit
                + _ntp_timestamp(recv_s)  # receive
                + _ntp_timestamp(self.now_s())  # transmit
            )
            self.requests += 1
            with contextlib.suppress(OSError):
                self._sock.sendto(reply, addr)

    def start(self) -> FakeNtpServer:
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2.0)
        self._sock.close()

    def __enter__(self) -> FakeNtpServer:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()


# ---------------------------------------------------------------------------
# Hypothesis strategies for wire messages (built from the msgspec schema itself)
# ---------------------------------------------------------------------------

FUZZ_EXAMPLES = 10_000 if CI else 500
"""Examples per codec fuzz property: ≥ 10⁴ under CI=true (issue 2), fewer locally."""


_DEFAULT = object()
"""Marks an optional field left out of a generated message."""


def _float_strategy(info: Any) -> Any:
    from hypothesis import strategies as st

    lo = info.ge if info.ge is not None else info.gt
    hi = info.le if info.le is not None else info.lt
    return st.floats(
        min_value=lo,
        max_value=hi,
        exclude_min=info.ge is None and info.gt is not None,
        exclude_max=info.le is None and info.lt is not None,
        allow_nan=False,
        allow_infinity=False,
    )


def _int_strategy(info: Any) -> Any:
    from hypothesis import strategies as st

    lo = info.ge if info.ge is not None else (info.gt + 1 if info.gt is not None else -(2**63))
    hi = info.le if info.le is not None else (info.lt - 1 if info.lt is not None else 2**63 - 1)
    return st.integers(min_value=lo, max_value=hi)


_ID_PATTERNS = ("^[a-z0-9][a-z0-9-]*$", "^([a-z0-9][a-z0-9-]*)?$")


def _str_strategy(info: Any) -> Any:
    from hypothesis import strategies as st

    lo, hi = info.min_length or 0, info.max_length if info.max_length is not None else 64
    if info.pattern in _ID_PATTERNS:
        # Ids ([a-z0-9][a-z0-9-]*): built directly, from_regex + a length filter is ~10x slower.
        first = st.sampled_from("abcdefghijklmnopqrstuvwxyz0123456789")
        rest = st.text(alphabet="abcdefghijklmnopqrstuvwxyz0123456789-", max_size=max(0, min(hi, 16) - 1))
        ident = st.builds(lambda a, b: a + b, first, rest)
        return st.just("") | ident if lo == 0 and info.pattern.endswith(")?$") else ident
    if info.pattern:
        return st.from_regex(info.pattern, fullmatch=True).filter(lambda s: lo <= len(s) <= hi)
    return st.text(min_size=lo, max_size=min(hi, 64))


def strategy_for_type(info: Any, max_list: int = 3) -> Any:
    """A hypothesis strategy of valid values for a ``msgspec.inspect`` type (lists capped at ``max_list``)."""
    import msgspec.inspect as mi
    from hypothesis import strategies as st

    if isinstance(info, mi.StructType):
        # Optional fields are sometimes left out (the default applies), sometimes drawn.
        fields = {
            f.name: strategy_for_type(f.type, max_list)
            if f.required
            else st.just(_DEFAULT) | strategy_for_type(f.type, max_list)
            for f in info.fields
        }
        cls = info.cls

        def build(values: dict[str, Any]) -> Any:
            return cls(**{k: v for k, v in values.items() if v is not _DEFAULT})

        return st.fixed_dictionaries(fields).map(build)
    if isinstance(info, mi.FloatType):
        return _float_strategy(info)
    if isinstance(info, mi.IntType):
        return _int_strategy(info)
    if isinstance(info, mi.StrType):
        return _str_strategy(info)
    if isinstance(info, mi.BoolType):
        return st.booleans()
    if isinstance(info, mi.NoneType):
        return st.none()
    if isinstance(info, mi.LiteralType):
        return st.sampled_from(info.values)
    if isinstance(info, mi.UnionType):
        return st.one_of(*(strategy_for_type(t, max_list) for t in info.types))
    if isinstance(info, mi.ListType):
        lo = info.min_length or 0
        hi = info.max_length if info.max_length is not None else max_list
        return st.lists(strategy_for_type(info.item_type, max_list), min_size=lo, max_size=max(lo, min(hi, max_list)))
    raise TypeError(f"no strategy for schema type {info!r}")


def message_strategy(msg_type: type, max_list: int = 3) -> Any:
    """Valid instances of a wire message type, e.g. ``message_strategy(Features)``."""
    import msgspec.inspect as mi

    return strategy_for_type(mi.type_info(msg_type), max_list)


def decode_protobuf(schema_name: str, schema_data: bytes, payload: bytes) -> Any:
    """A protobuf message (Foxglove's well-known types) decoded with the FileDescriptorSet its channel carries."""
    from google.protobuf import descriptor_pb2, descriptor_pool, message_factory

    fds = descriptor_pb2.FileDescriptorSet.FromString(schema_data)
    pool = descriptor_pool.DescriptorPool()
    for fd in fds.file:
        pool.Add(fd)
    cls = message_factory.GetMessageClass(pool.FindMessageTypeByName(schema_name))
    return cls.FromString(payload)
