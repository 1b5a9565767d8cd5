"""The supervisor: restarts with back-off, stops whole process groups (no orphans)."""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

import pytest

from common.site import load_site
from panostereo.launcher import ProcessPlan, Supervisor, client_endpoint, site_plans
from tests.support import wait_for


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    # A zombie still answers kill(0); look at its state.
    try:
        return Path(f"/proc/{pid}/stat").read_text().split()[2] != "Z"
    except OSError:
        return False


def test_crashing_process_is_restarted_with_growing_backoff(tmp_path: Path) -> None:
    events: list[str] = []
    plan = ProcessPlan("crash", [sys.executable, "-c", "import sys; sys.exit(3)"], log_path=tmp_path / "crash.log")
    sup = Supervisor([plan], backoff_min_s=0.1, backoff_max_s=0.4, on_event=events.append)
    sup.start()
    try:
        wait_for(lambda: (sup.poll(), sup.restarts()["crash"] >= 3)[1], 20, "three restarts")
    finally:
        sup.stop()
    delays = [float(e.split("restart in ")[1].split(" s")[0]) for e in events if "restart in" in e]
    assert delays[:3] == [0.1, 0.2, 0.4]
    assert all("exited with code 3" in e for e in events if "restart in" in e)


def test_stop_terminates_the_process_and_its_children(tmp_path: Path) -> None:
    pidfile = tmp_path / "grandchild.pid"
    code = (
        "import subprocess, sys, time\n"
        f"p = subprocess.Popen([sys.executable, '-c', 'import time; time.sleep(60)'])\n"
        f"open({str(pidfile)!r}, 'w').write(str(p.pid))\n"
        "time.sleep(60)\n"
    )
    sup = Supervisor([ProcessPlan("parent", [sys.executable, "-c", code])], grace_s=2.0)
    sup.start()
    try:
        wait_for(lambda: pidfile.exists() and pidfile.read_text().strip(), 20, "grandchild pid")
        parent = sup.pids()["parent"]
        grandchild = int(pidfile.read_text())
        assert parent is not None and _alive(parent) and _alive(grandchild)
    finally:
        t0 = time.monotonic()
        codes = sup.stop()
    assert codes["parent"] is not None and codes["parent"] != 0
    assert time.monotonic() - t0 < 5
    wait_for(lambda: not _alive(grandchild), 5, "grandchild to be gone")


def test_no_restart_when_disabled(tmp_path: Path) -> None:
    sup = Supervisor([ProcessPlan("once", [sys.executable, "-c", "pass"], restart=False)], backoff_min_s=0.05)
    sup.start()
    wait_for(lambda: (sup.poll(), sup.exit_codes()["once"] == 0)[1], 20, "exit")
    time.sleep(0.2)
    sup.poll()
    assert sup.restarts()["once"] == 0 and sup.pids()["once"] is None


@pytest.mark.parametrize(
    ("listen", "client"),
    [("tcp/0.0.0.0:7447", "tcp/127.0.0.1:7447"), ("tcp/127.0.0.1:9000", "tcp/127.0.0.1:9000")],
)
def test_client_endpoint(listen: str, client: str) -> None:
    assert client_endpoint(listen) == client


def test_site_plans_pick_host_and_build_argv(tmp_path: Path) -> None:
    (tmp_path / "n1.toml").write_text('[node]\nid = "n1"\n')
    (tmp_path / "m.toml").write_text('[manager]\nid = "m"\n')
    (tmp_path / "a.toml").write_text('[agent]\nid = "a"\n')
    (tmp_path / "site.toml").write_text(
        '[site]\nname = "t"\n'
        '[[process]]\nname = "n1"\ncommand = "node"\nconfig = "n1.toml"\nhost = "cam1"\n'
        '[[process]]\nname = "m"\ncommand = "manager"\nconfig = "m.toml"\n'
        '[[process]]\nname = "a"\ncommand = "agent"\nconfig = "a.toml"\nargs = ["record", "x.mcap"]\n'
    )
    site = load_site(tmp_path / "site.toml")
    local = site_plans(site, connect="tcp/127.0.0.1:1", env={"A": "1"}, python="py")
    assert [p.name for p in local] == ["m", "a"]
    # A site's manager gets the site, whose sensor nodes are the ones it fuses.
    site_file = str((tmp_path / "site.toml").resolve())
    assert local[0].argv == ["py", "-m", "panostereo", "manager", "--config", str(tmp_path / "m.toml"),
                             "--connect", "tcp/127.0.0.1:1", "--site", site_file]  # fmt: skip
    assert local[1].argv[:6] == ["py", "-m", "panostereo", "agent", "record", "x.mcap"]
    assert [p.name for p in site_plans(site, host="cam1")] == ["n1"]
    assert "--connect" not in site_plans(site, host="cam1")[0].argv


def test_one_rule_says_where_a_site_s_router_listens_and_its_processes_connect(tmp_path: Path) -> None:
    from common.errors import ConfigError
    from panostereo.launcher import site_endpoints

    (tmp_path / "site.toml").write_text('[site]\nname = "s"\nrouter = "tcp/0.0.0.0:7447"\n')
    site = load_site(tmp_path / "site.toml")
    assert site_endpoints(site) == ("tcp/0.0.0.0:7447", "tcp/127.0.0.1:7447")
    assert site_endpoints(site, listen="tcp/127.0.0.1:7500") == ("tcp/127.0.0.1:7500", "tcp/127.0.0.1:7500")
    assert site_endpoints(site, connect="tcp/10.0.0.1:7447", router=False) == (None, "tcp/10.0.0.1:7447")
    assert site_endpoints(site, router=False) == (None, None)  # each process's own config
    for bad in ({"connect": "tcp/h:1", "listen": "tcp/h:2"}, {"listen": "tcp/h:2", "router": False}):
        with pytest.raises(ConfigError, match="--"):
            site_endpoints(site, **bad)  # type: ignore[arg-type]


def test_a_process_that_exits_early_is_reported_with_the_end_of_its_own_log(tmp_path: Path) -> None:
    events: list[str] = []
    code = "import sys; print('starting'); print('error: unknown key x', file=sys.stderr); sys.exit(1)"
    plan = ProcessPlan("bad", [sys.executable, "-c", code], log_path=tmp_path / "bad.log")
    sup = Supervisor([plan], backoff_min_s=0.05, max_restarts=1, on_event=events.append)
    sup.start()
    try:
        wait_for(lambda: (sup.poll(), any("gave up" in e for e in events))[1], 20, "two exits")
    finally:
        sup.stop()
    assert sup.exited() == {"bad": 1}
    assert sup.log_tail("bad") == ["starting", "error: unknown key x"]  # this run's lines only, not the first run's
    assert all("its log ends:" in e and "error: unknown key x" in e for e in events if "exited" in e)
