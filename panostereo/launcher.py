"""Start, supervise and stop the processes of a site.

Each process runs in its own session (process group), so stopping it also
stops anything it started, and on Linux it gets SIGTERM if the supervisor
itself dies (``PR_SET_PDEATHSIG``): no orphans. A process that exits while it
should be running is restarted after a back-off that doubles from
``backoff_min_s`` up to ``backoff_max_s`` and resets once it has run for
``stable_s``. :meth:`Supervisor.stop` sends SIGTERM to every group (in reverse
start order), waits ``grace_s``, then SIGKILLs what is left.
"""

from __future__ import annotations

import contextlib
import ctypes
import logging
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

from common.errors import ConfigError
from common.site import ProcessSpec, SiteConfig
from common.site import process_ids as site_process_ids

__all__ = [
    "EPOCH_ENV",
    "SEED_ENV",
    "START_ENV",
    "STATE_ENV",
    "ProcessPlan",
    "Supervisor",
    "client_endpoint",
    "process_ids",
    "router_plan",
    "site_endpoints",
    "site_plans",
]

logger = logging.getLogger(__name__)

EPOCH_ENV = "PANOSTEREO_EPOCH_NS"
START_ENV = "PANOSTEREO_START_FILE"
"""A file a launcher writes once every process is up; recorded sources play frame 1 at the epoch it holds."""
SEED_ENV = "PANOSTEREO_SEED"
STATE_ENV = "PANOSTEREO_STATE_DIR"
LOG_TAIL_LINES = 8
"""How many of its last log lines are shown when a process exits before it has run ``stable_s``."""


@dataclass(frozen=True, slots=True)
class ProcessPlan:
    """How to start one process."""

    name: str
    argv: list[str]
    env: dict[str, str] = field(default_factory=dict)
    """Added to the supervisor's environment."""
    log_path: Path | None = None
    """Where stdout and stderr go (None: inherited)."""
    restart: bool = True


def _pdeathsig() -> None:  # pragma: no cover - runs in the child between fork and exec
    with contextlib.suppress(Exception):
        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG


@dataclass
class _Child:
    plan: ProcessPlan
    popen: subprocess.Popen[bytes] | None = None
    log: IO[bytes] | None = None
    started_at: float = 0.0
    restarts: int = 0
    backoff_s: float = 0.0
    next_start: float = 0.0
    last_rc: int | None = None
    gave_up: bool = False
    log_from: int = 0
    """Where the current run's output starts in the (appended) log file."""


class Supervisor:
    """Keeps a set of processes running.

    Args:
        plans: the processes, started in this order.
        restart: restart processes that exit (per plan ``restart`` too).
        backoff_min_s, backoff_max_s: restart delay range (doubling).
        stable_s: a run this long resets the back-off.
        grace_s: SIGTERM-to-SIGKILL wait at stop.
        max_restarts: give up on a process after this many restarts (0: never).
    """

    def __init__(
        self,
        plans: Sequence[ProcessPlan],
        *,
        restart: bool = True,
        backoff_min_s: float = 0.5,
        backoff_max_s: float = 30.0,
        stable_s: float = 30.0,
        grace_s: float = 5.0,
        max_restarts: int = 0,
        on_event: Callable[[str], None] | None = None,
    ) -> None:
        names = [p.name for p in plans]
        if len(set(names)) != len(names):
            raise ConfigError(f"process names must be unique, got {names}")
        self._children = [_Child(p) for p in plans]
        self._restart = restart
        self._bmin, self._bmax = backoff_min_s, backoff_max_s
        self._stable_s = stable_s
        self._grace_s = grace_s
        self._max_restarts = max_restarts
        self._on_event = on_event or (lambda text: logger.info("%s", text))

    # -- starting -----------------------------------------------------------
    def _spawn(self, c: _Child) -> None:
        env = dict(os.environ)
        env.update(c.plan.env)
        env.setdefault("PYTHONUNBUFFERED", "1")
        out: Any = None
        if c.plan.log_path is not None:
            c.plan.log_path.parent.mkdir(parents=True, exist_ok=True)
            if c.log is None:
                c.log = c.plan.log_path.open("ab")
            c.log.flush()
            c.log_from = c.log.tell()
            out = c.log
        try:
            c.popen = subprocess.Popen(  # argv from the site file, no shell
                c.plan.argv,
                env=env,
                stdin=subprocess.DEVNULL,
                stdout=out,
                stderr=subprocess.STDOUT if out is not None else None,
                start_new_session=True,
                preexec_fn=_pdeathsig if sys.platform.startswith("linux") else None,  # noqa: PLW1509
            )
        except OSError as err:
            raise ConfigError(f"cannot start process {c.plan.name!r} ({c.plan.argv[0]}): {err.strerror}") from err
        c.started_at = time.monotonic()
        self._on_event(f"started {c.plan.name} (pid {c.popen.pid})")

    def start(self) -> None:
        """Start every process."""
        for c in self._children:
            self._spawn(c)

    # -- supervising --------------------------------------------------------
    def poll(self) -> None:
        """Notice exits and (re)start processes whose back-off has elapsed; call it often."""
        now = time.monotonic()
        for c in self._children:
            if c.popen is not None:
                rc = c.popen.poll()
                if rc is None:
                    if c.backoff_s and now - c.started_at >= self._stable_s:
                        c.backoff_s = 0.0
                    continue
                c.last_rc = rc
                c.popen = None
                ran = now - c.started_at
                early = ran < self._stable_s
                tail = self.log_tail(c.plan.name) if early else []
                said = ("; its log ends:\n    " + "\n    ".join(tail)) if tail else ""
                if not (self._restart and c.plan.restart):
                    self._on_event(f"{c.plan.name} exited with code {rc} after {ran:.1f} s{said}")
                    continue
                if self._max_restarts and c.restarts >= self._max_restarts:
                    c.gave_up = True
                    self._on_event(f"{c.plan.name} exited with code {rc}; gave up after {c.restarts} restarts{said}")
                    continue
                c.backoff_s = self._bmin if not c.backoff_s else min(self._bmax, c.backoff_s * 2)
                c.next_start = now + c.backoff_s
                self._on_event(
                    f"{c.plan.name} exited with code {rc} after {ran:.1f} s; restart in {c.backoff_s:.1f} s{said}"
                )
            elif not c.gave_up and self._restart and c.plan.restart and c.last_rc is not None and now >= c.next_start:
                c.restarts += 1
                self._spawn(c)

    def run(self, should_stop: Callable[[float], bool], poll_s: float = 0.2) -> None:
        """Poll until ``should_stop(poll_s)`` returns True (it may sleep up to ``poll_s``)."""
        while True:
            self.poll()
            if should_stop(poll_s):
                return

    # -- state --------------------------------------------------------------
    def pids(self) -> dict[str, int | None]:
        return {c.plan.name: (c.popen.pid if c.popen is not None else None) for c in self._children}

    def restarts(self) -> dict[str, int]:
        return {c.plan.name: c.restarts for c in self._children}

    def alive(self, name: str) -> bool:
        c = next(c for c in self._children if c.plan.name == name)
        return c.popen is not None and c.popen.poll() is None

    def exit_codes(self) -> dict[str, int | None]:
        return {c.plan.name: c.last_rc for c in self._children}

    def exited(self) -> dict[str, int]:
        """Processes that have exited since they were started (restarted or not), with their last exit code."""
        return {c.plan.name: c.last_rc for c in self._children if c.last_rc is not None}

    def log_tail(self, name: str, lines: int = LOG_TAIL_LINES) -> list[str]:
        """The last non-empty lines its latest run wrote to a process's log file (none when its output is not
        logged to a file)."""
        c = next(c for c in self._children if c.plan.name == name)
        path = c.plan.log_path
        if path is None:
            return []
        if c.log is not None:
            c.log.flush()
        try:
            with path.open("rb") as fh:
                fh.seek(max(c.log_from, path.stat().st_size - 16_384))
                text = fh.read().decode("utf-8", errors="replace")
        except OSError:
            return []
        return [line.rstrip() for line in text.splitlines() if line.strip()][-lines:]

    # -- stopping -----------------------------------------------------------
    @staticmethod
    def _signal_group(p: subprocess.Popen[bytes], sig: int) -> None:
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(p.pid, sig)

    def stop(self) -> dict[str, int | None]:
        """SIGTERM every process group (reverse order), wait, SIGKILL leftovers; returns exit codes."""
        running = [c for c in reversed(self._children) if c.popen is not None]
        for c in running:
            assert c.popen is not None
            if c.popen.poll() is None:
                self._signal_group(c.popen, signal.SIGTERM)
        deadline = time.monotonic() + self._grace_s
        for c in running:
            assert c.popen is not None
            try:
                c.last_rc = c.popen.wait(timeout=max(0.0, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                self._on_event(f"{c.plan.name} did not stop within {self._grace_s:g} s: killing it")
                self._signal_group(c.popen, signal.SIGKILL)
                c.last_rc = c.popen.wait()
            # Anything the process left in its group goes too.
            self._signal_group(c.popen, signal.SIGKILL)
            c.popen = None
        for c in self._children:
            c.gave_up = True
            if c.log is not None:
                c.log.close()
                c.log = None
        return self.exit_codes()


# ---------------------------------------------------------------------------
# Site -> process plans
# ---------------------------------------------------------------------------


def client_endpoint(listen: str) -> str:
    """The endpoint local clients use to reach a router listening on ``listen`` (0.0.0.0 -> 127.0.0.1)."""
    proto, _, rest = listen.partition("/")
    host, _, port = rest.rpartition(":")
    if host in ("0.0.0.0", "[::]", "::", ""):
        host = "127.0.0.1"
    return f"{proto}/{host}:{port}"


def site_endpoints(
    site: SiteConfig, *, listen: str | None = None, connect: str | None = None, router: bool = True
) -> tuple[str | None, str | None]:
    """Where a site's router listens and where its processes connect: the one rule ``demo`` and ``up`` share.

    Args:
        listen: where to run the router (default: the site's ``router``).
        connect: an existing router to join instead (no router is started; ``listen`` must not be given).
        router: whether a router runs here (``up --router``, ``demo`` unless ``connect``).

    Returns:
        (the router's listen endpoint, or None when no router runs here; the endpoint every process connects
        to, or None to leave it to each process's own config: ``up`` on a host without the router).

    Raises:
        ConfigError: both ``listen`` and ``connect``, or ``listen`` without a router.
    """
    if connect and (listen or router):
        raise ConfigError("--connect joins a router that runs elsewhere: it cannot go with --listen or --router")
    if connect:
        return None, connect
    if not router:
        if listen:
            raise ConfigError("--listen says where this host's router listens: add --router (or use --connect)")
        return None, None
    where = listen or site.site.router
    return where, client_endpoint(where)


def router_plan(listen: list[str], python: str = sys.executable, log_path: Path | None = None) -> ProcessPlan:
    argv = [python, "-m", "panostereo", "router"]
    for ep in listen:
        argv += ["--listen", ep]
    return ProcessPlan("router", argv, log_path=log_path)


def _argv(proc: ProcessSpec, config: Path, python: str, connect: str | None, site_path: str) -> list[str]:
    net = ["--connect", connect] if connect else []
    base = [python, "-m", "panostereo", proc.command]
    if proc.command == "agent":
        # agent ACTION [ACTION ARGS] --config FILE: the subcommand comes first.
        return [*base, *proc.args, "--config", str(config), *net]
    if proc.command == "manager" and site_path:
        # The site says which sensors its manager fuses: anything else under the prefix is refused.
        net = [*net, "--site", str(Path(site_path).resolve())]
    return [*base, "--config", str(config), *net, *proc.args]


def site_plans(
    site: SiteConfig,
    *,
    host: str = "localhost",
    connect: str | None = None,
    env: dict[str, str] | None = None,
    log_dir: Path | None = None,
    python: str = sys.executable,
    commands: Sequence[str] = ("node", "manager", "agent"),
) -> list[ProcessPlan]:
    """One plan per ``[[process]]`` of the site that runs on ``host``.

    Args:
        host: which processes to start (``localhost`` also matches processes without a host).
        connect: router endpoint to pass as ``--connect`` (None: the process config's own).
        env: extra environment (epoch, seed, state dir).
        log_dir: write ``<name>.log`` files there (None: inherit stdout/stderr).

    Raises:
        ConfigError: a process config file is missing.
    """
    plans = []
    for proc in site.process:
        if proc.command not in commands:
            continue
        if proc.host != host and not (host == "localhost" and proc.host in ("", "localhost")):
            continue
        cfg = site.resolve(proc.config)
        if not cfg.is_file():
            raise ConfigError(f"{site.path}: process {proc.name!r}: config {proc.config!r} not found ({cfg})")
        log = log_dir / f"{proc.name}.log" if log_dir is not None else None
        plans.append(ProcessPlan(proc.name, _argv(proc, cfg, python, connect, site.path), dict(env or {}), log))
    return plans


def process_ids(site: SiteConfig) -> dict[str, tuple[str, str]]:
    """Process name -> (command, the sensor/manager/agent id its config declares)."""
    return site_process_ids(site)
