"""Fixtures every test can use: managed subprocesses, a real router, hypothesis profiles.

* ``spawn``: start a subprocess whose output is captured to files; stopped at
  teardown (SIGTERM, wait, SIGKILL), its log printed when the test failed.
* ``router``: one ``panostereo router`` for the whole session, on a free
  loopback port (``router.endpoint``).
* ``router_factory``: start private routers (e.g. to restart one); stopped at teardown.

Hypothesis profiles: ``ci`` under ``CI=true`` (more examples, derandomised so
CI runs are reproducible), ``dev`` otherwise. Property tests that need a
specific example count (the codec fuzz: ≥ 10⁴ under CI) set it themselves
with ``tests.support.FUZZ_EXAMPLES``-style constants.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, settings

_REPO = str(Path(__file__).resolve().parent.parent)
INTEGRATION = "tests/integration/"
"""Where the tests that start real processes are (node ids are relative to the repository)."""
ALONGSIDE = ("tests/integration/test_bad_input.py",)
"""Integration tests that start no site, only short commands each judged by its one line of output, and no timing:
under pytest-xdist they may run beside the others."""
if _REPO not in sys.path:  # so `tests.support` imports from any cwd (pyproject's pythonpath may not be set)
    sys.path.insert(0, _REPO)

from tests.support import ManagedProcess, RouterProcess, in_ci, start_router  # noqa: E402
from tests.support import spawn as spawn_process  # noqa: E402

settings.register_profile(
    "ci",
    max_examples=100,
    deadline=None,
    derandomize=True,
    print_blob=True,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.register_profile("dev", max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
settings.load_profile("ci" if in_ci() else "dev")


@pytest.hookimpl(wrapper=True, tryfirst=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo[None]) -> Any:
    """Remember each phase's report on the item so fixtures can tell whether the test failed."""
    rep = yield
    setattr(item, f"rep_{rep.when}", rep)
    return rep


def _failed(request: pytest.FixtureRequest) -> bool:
    rep = getattr(request.node, "rep_call", None) or getattr(request.node, "rep_setup", None)
    return bool(rep is not None and rep.failed)


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config: pytest.Config, log: Any) -> Any:
    """Under pytest-xdist with ``--dist loadgroup`` (what ``make test`` runs) the integration tests are one work unit,
    run one after another on one worker: each starts a router and a site's processes, and their readiness windows
    assume one such site at a time. The unit and property tests (and :data:`ALONGSIDE`) share the other workers.
    (xdist's own ``xdist_group`` marks rename node ids, which pytest 9.2 no longer allows; this groups by path.)"""
    if config.getvalue("dist") != "loadgroup":
        return None
    from xdist.scheduler import LoadScopeScheduling

    class IntegrationTogether(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            together = nodeid.startswith(INTEGRATION) and not nodeid.startswith(ALONGSIDE)
            return "integration" if together else nodeid

    return IntegrationTogether(config, log)


@pytest.fixture
def spawn(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[Callable[..., ManagedProcess]]:
    """``spawn(args, env=None, name=None, cwd=None) -> ManagedProcess``, stopped at teardown; logs under tmp_path."""
    procs: list[ManagedProcess] = []

    def _spawn(
        args: Sequence[Any], env: dict[str, str] | None = None, name: str | None = None, cwd: Any = None
    ) -> ManagedProcess:
        proc = spawn_process(args, env=env, cwd=cwd, log_dir=tmp_path / "logs", name=name)
        procs.append(proc)
        return proc

    yield _spawn
    for proc in reversed(procs):
        proc.stop()
    if _failed(request):
        for proc in procs:
            sys.stderr.write(proc.log())


@pytest.fixture(scope="session")
def router(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RouterProcess]:
    """One router for the session on a free loopback port; ``router.endpoint`` is ``tcp/127.0.0.1:<port>``."""
    r = start_router(log_dir=tmp_path_factory.mktemp("router"))
    yield r
    rc = r.stop()
    if rc != 0:
        sys.stderr.write(f"session router exited with {rc}\n{r.proc.log()}")


@pytest.fixture
def router_factory(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[Callable[..., RouterProcess]]:
    """``router_factory(port=None) -> RouterProcess``: private routers, stopped at teardown."""
    started: list[RouterProcess] = []

    def _start(port: int | None = None) -> RouterProcess:
        r = start_router(port=port, log_dir=tmp_path / "routers")
        started.append(r)
        return r

    yield _start
    for r in reversed(started):
        r.stop()
    if _failed(request):
        for r in started:
            sys.stderr.write(r.proc.log())
