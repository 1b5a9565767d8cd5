"""Security of a site (issue 8): TLS + mutual TLS + default-deny access control, and user/password.

A real ``panostereo router`` runs with the configs that ``deploy/security/make-certs.sh`` and
``deploy/security/make_configs.py`` produce (into a temp dir, never the repo). Legitimate
sensor, manager and agent clients are zenoh sessions holding their own certificates; each
is a separate transport to the router, which is where the rules are enforced.

Every negative case is paired with the positive one that shows the test could fail: the
same receiver does get the legitimate message, through the same router, in the same test.
"""

from __future__ import annotations

import datetime
import json
import re
import shutil
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from common.codec import decode, encode
from common.errors import SessionError
from common.keys import Keys
from common.schema import Features, Pose, PtzCommand, PtzReply, PtzRequest, SensorInfo, Track, TrackSet
from common.session import SessionSettings, open_session
from tests.support import REPO, ManagedProcess, free_port, spawn, wait_for, wait_for_port

pytestmark = [pytest.mark.integration, pytest.mark.timeout(120)]

SECURITY = REPO / "deploy" / "security"
KEYS = Keys("sectest")
SENSORS = ("c1", "c2")
REFUSE_MS = 1200
"""Connect timeout of clients expected to be refused (auth failures look like timeouts)."""
SETTLE_S = 0.5
"""After a marker proves the path is flowing, how long a forged sample is given to show up."""


def _run(args: list[str]) -> str:
    res = subprocess.run(args, cwd=REPO, capture_output=True, text=True, timeout=60, check=False)
    assert res.returncode == 0, f"{args} failed:\n{res.stdout}\n{res.stderr}"
    return res.stdout


def _make_configs(certs: str | Path, out: Path, *args: str) -> str:
    """Run deploy/security/make_configs.py with ``--certs``, ``--out`` and ``args``."""
    return _run([sys.executable, str(SECURITY / "make_configs.py"), "--certs", str(certs), "--out", str(out), *args])


def _json5(path: Path) -> dict[str, Any]:
    """Our generated JSON5 is JSON plus leading ``//`` comment lines."""
    return dict(json.loads(re.sub(r"^\s*//.*$", "", path.read_text(), flags=re.M)))


@dataclass
class SecureSite:
    certs: Path
    foreign: Path
    cfg: Path
    tls_port: int
    tcp_port: int
    router: ManagedProcess
    usr_router: ManagedProcess

    @property
    def tls(self) -> str:
        return f"tls/localhost:{self.tls_port}"

    def users(self) -> dict[str, str]:
        return dict(line.split(":", 1) for line in (self.cfg / "users.txt").read_text().split())


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Iterator[SecureSite]:
    root = tmp_path_factory.mktemp("secure-site")
    certs, foreign, cfg = root / "certs", root / "foreign", root / "cfg"
    ids = " ".join(SENSORS)
    who = ("--sensors", ids, "--managers", "m1 mz", "--agents", "a1")
    _run(["bash", str(SECURITY / "make-certs.sh"), "--out", str(certs), *who])
    # Another CA issuing certificates with the very same names: must not be trusted.
    _run(["bash", str(SECURITY / "make-certs.sh"), "--out", str(foreign), *who, "--ca-name", "evil-ca"])
    tls_port, tcp_port = free_port(), free_port()
    # mz: a zone's manager, whose zone's only camera is c1.
    rules = ("--sensors", ids, "--managers", "m1 mz=c1", "--agents", "a1")
    _make_configs(certs, cfg, "--prefix", KEYS.prefix, *rules, "--listen", f"tls/127.0.0.1:{tls_port}",
                  "--listen-tcp", f"tcp/127.0.0.1:{tcp_port}")  # fmt: skip
    # As deployed: the router's dictionary goes where its other files are (the folder --certs names).
    shutil.copy(cfg / "users.txt", certs / "users.txt")
    logs = root / "logs"
    router = spawn(
        [
            sys.executable,
            "-m",
            "panostereo",
            "router",
            "--zenoh-config",
            str(cfg / "router-tls.json5"),
            "--zenoh-log",
            "warn",
        ],
        log_dir=logs,
        name="router-tls",
    )
    usr_router = spawn(
        [sys.executable, "-m", "panostereo", "router", "--zenoh-config", str(cfg / "router-usrpwd.json5")],
        log_dir=logs,
        name="router-usrpwd",
    )
    try:
        wait_for_port(tls_port, 20.0, proc=router)
        wait_for_port(tcp_port, 20.0, proc=usr_router)
        yield SecureSite(certs, foreign, cfg, tls_port, tcp_port, router, usr_router)
    finally:
        for proc in (router, usr_router):
            proc.stop()
        assert router.returncode == 0, router.log()
        assert usr_router.returncode == 0, usr_router.log()


def _settings(config_file: Path, connect: str, timeout_ms: int = 10_000, **kw: Any) -> SessionSettings:
    return SessionSettings(
        mode="client", config_file=str(config_file), connect=[connect], connect_timeout_ms=timeout_ms, **kw
    )


def _tls_client(site: SecureSite, name: str) -> Any:
    return open_session(_settings(site.cfg / f"{name}.json5", site.tls))


def _variant(site: SecureSite, tmp_path: Path, name: str, **tls_changes: Any) -> Path:
    """A copy of ``name``'s client config with TLS fields replaced (None deletes one)."""
    conf = _json5(site.cfg / f"{name}.json5")
    tls = conf["transport"]["link"]["tls"]
    for k, v in tls_changes.items():
        if v is None:
            tls.pop(k, None)
        else:
            tls[k] = v
    path = tmp_path / f"{name}-variant.json5"
    path.write_text(json.dumps(conf))
    return path


class Collector:
    """Decoded samples that reached one subscriber from other sessions, thread-safe."""

    def __init__(self, session: Any, key_expr: str, msg_type: type) -> None:
        self._lock = threading.Lock()
        self.items: list[tuple[str, Any]] = []
        self._type = msg_type
        import zenoh

        # REMOTE only: a session's own puts are delivered to it locally, before any router rule applies.
        self._sub = session.declare_subscriber(key_expr, self._on, allowed_origin=zenoh.Locality.REMOTE)

    def _on(self, sample: Any) -> None:
        msg: Any = decode(sample.payload.to_bytes(), self._type)
        with self._lock:
            self.items.append((str(sample.key_expr), msg))

    def where(self, pred: Any) -> list[tuple[str, Any]]:
        with self._lock:
            return [kv for kv in self.items if pred(kv[0], kv[1])]


def _features(sensor_id: str, seq: int, frame: int = 0) -> Features:
    return Features(sensor_id=sensor_id, seq=seq, stamp_ns=1_700_000_000_000_000_000 + seq, frame_index=frame)


def _trackset(manager_id: str, seq: int) -> TrackSet:
    t = Track(
        manager_id=manager_id,
        seq=seq,
        stamp_ns=1,
        track_id=f"{manager_id}-{seq}",
        x_m=1.0,
        y_m=2.0,
        height_m=1.7,
        vx_mps=0.0,
        vy_mps=0.0,
        cov_xx_m2=0.01,
        cov_xy_m2=0.0,
        cov_yy_m2=0.01,
        state="confirmed",
        method="triangulation",
    )
    return TrackSet(manager_id=manager_id, seq=seq, stamp_ns=1, tracks=[t])


def _deliver_until(put: Any, pred: Any, what: str, timeout_s: float = 10.0) -> Any:
    """Re-put until the receiver sees it (subscriptions take a moment to propagate)."""

    def seen() -> Any:
        put()
        return pred()

    return wait_for(seen, timeout_s, what, poll_s=0.05)


# ---------------------------------------------------------------------------
# The certificates
# ---------------------------------------------------------------------------


def _not_after(pem: Path) -> datetime.datetime:
    text = _openssl("x509", "-in", str(pem), "-noout", "-enddate").split("=", 1)[1]
    return datetime.datetime.strptime(" ".join(text.split()), "%b %d %H:%M:%S %Y %Z")


def _openssl(*args: str) -> str:
    res = subprocess.run(["openssl", *args], capture_output=True, text=True, timeout=30, check=False)
    assert res.returncode == 0, res.stderr
    return res.stdout


def test_make_certs_roles_names_and_modes(tmp_path: Path) -> None:
    out = tmp_path / "certs"
    make = ["bash", str(SECURITY / "make-certs.sh"), "--out", str(out), "--sensors", "c1", "--managers", "m1"]
    make += ["--agents", "a1 a2:5"]  # make_configs.py's PTZ cap suffix is taken too
    _run([*make, "--host", "router.example", "--host", "10.1.2.3"])
    names = ["router", "sensor-c1", "manager-m1", "agent-a1", "agent-a2"]
    for name in names:
        pem = str(out / f"{name}.pem")
        assert _openssl("verify", "-CAfile", str(out / "ca.pem"), pem).strip().endswith("OK")
        text = _openssl("x509", "-in", pem, "-noout", "-subject", "-ext", "subjectAltName,basicConstraints")
        assert f"CN = {name}" in text or f"CN={name}" in text, text
        assert "CA:FALSE" in text
        for san in ("DNS:localhost", "IP Address:127.0.0.1", "DNS:router.example", "IP Address:10.1.2.3"):
            assert san in text, text
        assert (out / f"{name}.key").read_text().startswith("-----BEGIN PRIVATE KEY-----")  # PKCS#8 for rustls
        assert (out / f"{name}.key").stat().st_mode & 0o077 == 0, f"{name}.key is readable by others"
    assert "CA:TRUE" in _openssl("x509", "-in", str(out / "ca.pem"), "-noout", "-ext", "basicConstraints")
    assert (out / "ca.key").stat().st_mode & 0o077 == 0
    # Re-running adds identities under the same CA (an existing site grows) and re-keys nobody else: adding a
    # camera as documented issues that camera's certificate and nothing else (no default manager or agent).
    ca_before = (out / "ca.pem").read_text()
    kept = {n: (out / f"{n}.pem").read_bytes() + (out / f"{n}.key").read_bytes() for n in names}
    said = _run(["bash", str(SECURITY / "make-certs.sh"), "--out", str(out), "--sensors", "c9"])
    assert "new: sensor-c9 (" in said, said
    assert (out / "ca.pem").read_text() == ca_before
    assert _openssl("verify", "-CAfile", str(out / "ca.pem"), str(out / "sensor-c9.pem")).strip().endswith("OK")
    assert {n: (out / f"{n}.pem").read_bytes() + (out / f"{n}.key").read_bytes() for n in names} == kept
    # --renew re-issues just the names given (new key too); a leaf never outlives its CA.
    said = _run(["bash", str(SECURITY / "make-certs.sh"), "--out", str(out), "--renew", "router", "--days", "9000"])
    assert (out / "router.key").read_bytes() != kept["router"][-len((out / "router.key").read_bytes()) :]
    assert (out / "agent-a1.pem").read_bytes() + (out / "agent-a1.key").read_bytes() == kept["agent-a1"]
    assert "new: router " in said
    assert _not_after(out / "router.pem") < _not_after(out / "ca.pem")
    _run(["bash", str(SECURITY / "make-certs.sh"), "--out", str(out), "--force"])
    assert (out / "ca.pem").read_text() != ca_before
    bad = subprocess.run([*make, "--sensors", "Bad_Id"], capture_output=True, text=True, timeout=30, check=False)
    assert bad.returncode != 0
    assert "Bad_Id" in bad.stderr


def test_configs_for_two_hosts_listen_where_told_and_keep_secrets_private(tmp_path: Path) -> None:
    """As in the README's two-host walk-through: both routers listen on the given host, the dictionary is named
    where the router's files are deployed (--certs), and no file holding a password is readable by others."""
    out = tmp_path / "site-certs"
    _make_configs("/etc/panostereo/certs", out, "--sensors", "cam1 cam2", "--managers", "mgr1", "--agents",
                  "a1 ops:10", "--listen", "tls/0.0.0.0:7447", "--router-host", "192.168.1.10")  # fmt: skip
    usr = _json5(out / "router-usrpwd.json5")
    assert usr["listen"]["endpoints"] == ["tcp/0.0.0.0:7448"]
    assert usr["transport"]["auth"]["usrpwd"]["dictionary_file"] == "/etc/panostereo/certs/users.txt"
    assert _json5(out / "router-tls.json5")["listen"]["endpoints"] == ["tls/0.0.0.0:7447"]
    assert _json5(out / "usrpwd" / "sensor-cam1.json5")["connect"]["endpoints"] == ["tcp/192.168.1.10:7448"]
    for secret in [out / "router-usrpwd.json5", out / "users.txt", *(out / "usrpwd").glob("*.json5")]:
        assert secret.stat().st_mode & 0o077 == 0, f"{secret.name} is readable by others"
    # Each agent may ask for PTZ views on its own key only.
    rules = {r["id"]: r for r in _json5(out / "router-tls.json5")["access_control"]["rules"]}
    assert "pano/@v1/manager/*/ptz/a1" in rules["agent-a1-query"]["key_exprs"]
    assert not [k for r in rules.values() if r["id"].startswith("agent-") for k in r["key_exprs"] if k.endswith("/ptz")]
    # ...and its PTZ priority cap goes into the managers' configs as written.
    from resource_manager.config import load_manager_config

    mgr = tmp_path / "manager.toml"
    mgr.write_text('[manager]\nid = "mgr1"\n\n' + (out / "ptz-priorities.toml").read_text())
    assert load_manager_config(mgr).ptz.max_priority == {"ops": 10}
    assert "agent-ops-query" in rules and "agent-ops" not in str(rules["agent-a1-query"])


# ---------------------------------------------------------------------------
# Who may connect
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["sensor-c1", "manager-m1", "agent-a1"])
def test_each_role_connects_with_its_certificate(site: SecureSite, name: str) -> None:
    with _tls_client(site, name) as s:
        assert s.info.routers_zid(), f"{name} sees no router"
    links_ok = site.router.alive
    assert links_ok, site.router.log()


ROUTER_SAYS = {
    "no client certificate": "NoCertificatesPresented|no certificates",
    "certificate from another CA": "UnknownIssuer",
    "expired certificate": "certificate expired",
    "client trusts another CA": "UnknownCA",
    "plain tcp to the tls port": "corrupt message",
}
"""What zenoh's log (WARN) says about each refused client, as rustls words it."""


def _expired_leaf(ca_dir: Path, name: str, out: Path) -> tuple[Path, Path]:
    """A certificate for ``name`` from the site CA that expired in 2020 (``openssl ca`` sets past dates)."""
    out.mkdir(parents=True, exist_ok=True)
    key, csr, pem = out / f"{name}.key", out / f"{name}.csr", out / f"{name}.pem"
    _openssl("genpkey", "-algorithm", "EC", "-pkeyopt", "ec_paramgen_curve:P-256", "-out", str(key))
    _openssl("req", "-new", "-key", str(key), "-subj", f"/CN={name}", "-out", str(csr))
    (out / "index.txt").write_text("")
    (out / "serial").write_text("1000\n")
    conf = out / "ca.cnf"
    conf.write_text(
        f"[ca]\ndefault_ca = c\n[c]\ndatabase = {out}/index.txt\nnew_certs_dir = {out}\nserial = {out}/serial\n"
        "default_md = sha256\npolicy = p\n[p]\ncommonName = supplied\n[ext]\nbasicConstraints = critical,CA:FALSE\n"
        "extendedKeyUsage = serverAuth,clientAuth\nsubjectAltName = DNS:localhost,IP:127.0.0.1\n"
    )
    _openssl("ca", "-batch", "-config", str(conf), "-cert", str(ca_dir / "ca.pem"), "-keyfile", str(ca_dir / "ca.key"),
             "-in", str(csr), "-out", str(pem), "-startdate", "20200101000000Z", "-enddate", "20200102000000Z",
             "-extensions", "ext", "-notext")  # fmt: skip
    return pem, key


@pytest.mark.parametrize(
    "case",
    [
        "no client certificate",
        "certificate from another CA",
        "expired certificate",
        "client trusts another CA",
        "plain tcp to the tls port",
    ],
)
def test_untrusted_peers_are_refused(site: SecureSite, tmp_path: Path, case: str) -> None:
    name = "sensor-c1"
    connect = site.tls
    if case == "expired certificate":
        pem, key = _expired_leaf(site.certs, name, tmp_path / "expired")
        cfg = _variant(site, tmp_path, name, connect_certificate=str(pem), connect_private_key=str(key))
    elif case == "no client certificate":
        # A client that does not do mutual TLS at all (no certificate, enable_mtls off).
        cfg = _variant(site, tmp_path, name, connect_certificate=None, connect_private_key=None, enable_mtls=False)
    elif case == "certificate from another CA":
        cfg = _variant(
            site,
            tmp_path,
            name,
            connect_certificate=str(site.foreign / f"{name}.pem"),
            connect_private_key=str(site.foreign / f"{name}.key"),
        )
    elif case == "client trusts another CA":  # the router cannot prove it is the site's router
        cfg = _variant(site, tmp_path, name, root_ca_certificate=str(site.foreign / "ca.pem"))
    else:
        cfg = site.cfg / f"{name}.json5"
        connect = f"tcp/127.0.0.1:{site.tls_port}"
    refused = _settings(cfg, connect, timeout_ms=REFUSE_MS)
    before = site.router.stdout_text()
    with pytest.raises(SessionError, match="cannot open a zenoh client session"), open_session(refused):
        pass
    # The router says why (panostereo router --zenoh-log warn): a refused client leaves a trace.
    why = ROUTER_SAYS[case]
    wait_for(lambda: re.search(why, site.router.stdout_text()[len(before) :]), 10.0, f"the router's log to say {why!r}")
    # ...and a legitimate client still gets in afterwards.
    with _tls_client(site, name) as s:
        assert s.info.routers_zid()


# ---------------------------------------------------------------------------
# What each identity may say
# ---------------------------------------------------------------------------


def test_forged_features_and_tracks_change_nothing(site: SecureSite) -> None:
    """An agent, another sensor and the manager cannot publish c1's features; only the manager publishes tracks."""
    with (
        _tls_client(site, "manager-m1") as mgr,
        _tls_client(site, "sensor-c1") as c1,
        _tls_client(site, "sensor-c2") as c2,
        _tls_client(site, "agent-a1") as agent,
        _tls_client(site, "agent-a1") as watcher,
    ):
        feats = Collector(mgr, KEYS.all_features, Features)
        sets = Collector(watcher, KEYS.tracks(), TrackSet)
        singles = Collector(watcher, KEYS.all_tracks, Track)
        token = agent.liveliness().declare_token(KEYS.agent("a1"))
        # The legitimate paths work: c1's features reach the manager, the manager's tracks reach an agent.
        _deliver_until(
            lambda: c1.put(KEYS.sensor_features("c1"), encode(_features("c1", 1))),
            lambda: feats.where(lambda k, m: m.seq == 1),
            "c1's own features at the manager",
        )
        _deliver_until(
            lambda: mgr.put(KEYS.tracks(), encode(_trackset("m1", 1))),
            lambda: sets.where(lambda k, m: m.seq == 1),
            "the manager's tracks at an agent",
        )
        # Forgeries, each of a message that would be accepted if delivered.
        forged_seq = 666
        agent.put(KEYS.sensor_features("c1"), encode(_features("c1", forged_seq)))
        c2.put(KEYS.sensor_features("c1"), encode(_features("c1", forged_seq)))
        mgr.put(KEYS.sensor_features("c2"), encode(_features("c2", forged_seq)))
        agent.put(KEYS.tracks(), encode(_trackset("m1", forged_seq)))
        c1.put(KEYS.tracks(), encode(_trackset("m1", forged_seq)))
        agent.put(KEYS.track("m1-666"), encode(_trackset("m1", forged_seq).tracks[0]))
        c2.put(KEYS.track("m1-666"), encode(_trackset("m1", forged_seq).tracks[0]))
        # Markers sent after the forgeries on the same transports, which must arrive.
        c1.put(KEYS.sensor_features("c1"), encode(_features("c1", 2)))
        c2.put(KEYS.sensor_features("c2"), encode(_features("c2", 2)))
        mgr.put(KEYS.tracks(), encode(_trackset("m1", 2)))
        wait_for(lambda: len(feats.where(lambda k, m: m.seq == 2)) == 2, 10.0, "both sensors' markers")
        wait_for(lambda: sets.where(lambda k, m: m.seq == 2), 10.0, "the manager's marker track set")
        wait_for(lambda: bool(mgr.liveliness().get(KEYS.agent("a1"), timeout=1.0)), 5.0, "the agent's own token")
        assert not wait_for_any(
            lambda: (
                feats.where(lambda k, m: m.seq == forged_seq)
                or sets.where(lambda k, m: m.seq == forged_seq)
                or singles.where(lambda k, m: True)
            ),
            SETTLE_S,
        ), (feats.items, sets.items, singles.items)
        token.undeclare()
        # The network still works after the attempts.
        c1.put(KEYS.sensor_features("c1"), encode(_features("c1", 3)))
        wait_for(lambda: feats.where(lambda k, m: m.seq == 3), 10.0, "c1's features after the attacks")


def _pose_of(status: Any, sensor_id: str) -> tuple[float, float, float] | None:
    est = next((p for p in status.poses if p.sensor_id == sensor_id), None)
    return None if est is None else (est.pose.x_m, est.pose.y_m, est.pose.yaw_rad)


def wait_for_any(pred: Any, timeout_s: float) -> bool:
    """True as soon as ``pred()`` is truthy within ``timeout_s``; False if it never is (bounded negative wait)."""
    try:
        wait_for(pred, timeout_s, "a forged sample", poll_s=0.02)
    except AssertionError:
        return False
    return True


def test_agents_cannot_read_raw_features_or_command_cameras(site: SecureSite) -> None:
    with (
        _tls_client(site, "manager-m1") as mgr,
        _tls_client(site, "sensor-c1") as c1,
        _tls_client(site, "agent-a1") as agent,
    ):
        seen_by_agent = Collector(agent, KEYS.all_features, Features)
        seen_by_mgr = Collector(mgr, KEYS.all_features, Features)
        ptz_at_c1 = Collector(c1, KEYS.sensor_ptz("c1"), PtzCommand)
        _deliver_until(
            lambda: c1.put(KEYS.sensor_features("c1"), encode(_features("c1", 1))),
            lambda: seen_by_mgr.where(lambda k, m: True),
            "c1's features at the manager",
        )
        cmd = PtzCommand(manager_id="m1", seq=1, stamp_ns=1, sensor_id="c1", pan_rad=0.5, tilt_rad=0.0)
        agent.put(KEYS.sensor_ptz("c1"), encode(msg_replace(cmd, seq=666)))
        _deliver_until(
            lambda: mgr.put(KEYS.sensor_ptz("c1"), encode(cmd)),
            lambda: ptz_at_c1.where(lambda k, m: m.seq == 1),
            "the manager's PTZ command at c1",
        )
        c1.put(KEYS.sensor_features("c1"), encode(_features("c1", 2)))
        wait_for(lambda: seen_by_mgr.where(lambda k, m: m.seq == 2), 10.0, "c1's second frame")
        assert not wait_for_any(lambda: seen_by_agent.items or ptz_at_c1.where(lambda k, m: m.seq == 666), SETTLE_S), (
            seen_by_agent.items,
            ptz_at_c1.items,
        )


def test_a_zone_manager_reads_and_commands_its_zones_cameras_only(site: SecureSite) -> None:
    """mz is written ``mz=c1``: it gets c1's frames and moves c1, never c2; m1, written without cameras, does both."""
    with (
        _tls_client(site, "manager-mz") as mz,
        _tls_client(site, "manager-m1") as m1,
        _tls_client(site, "sensor-c1") as c1,
        _tls_client(site, "sensor-c2") as c2,
    ):
        frames_at_mz = Collector(mz, KEYS.sensor_features("c1"), Features)
        stolen_at_mz = Collector(mz, KEYS.sensor_features("c2"), Features)
        frames_at_m1 = Collector(m1, KEYS.all_features, Features)
        ptz_at = {sid: Collector(s, KEYS.sensor_ptz(sid), PtzCommand) for sid, s in (("c1", c1), ("c2", c2))}
        _deliver_until(
            lambda: c1.put(KEYS.sensor_features("c1"), encode(_features("c1", 1))),
            lambda: frames_at_mz.where(lambda k, m: True),
            "c1's features at the zone manager",
        )
        _deliver_until(
            lambda: c2.put(KEYS.sensor_features("c2"), encode(_features("c2", 1))),
            lambda: frames_at_m1.where(lambda k, m: m.sensor_id == "c2"),
            "c2's features at the site manager",
        )
        cmd = PtzCommand(manager_id="mz", seq=1, stamp_ns=1, sensor_id="c1", pan_rad=0.5, tilt_rad=0.0)
        mz.put(KEYS.sensor_ptz("c2"), encode(msg_replace(cmd, sensor_id="c2", seq=666)))
        _deliver_until(
            lambda: mz.put(KEYS.sensor_ptz("c1"), encode(cmd)),
            lambda: ptz_at["c1"].where(lambda k, m: m.seq == 1),
            "the zone manager's PTZ command at c1",
        )
        c2.put(KEYS.sensor_features("c2"), encode(_features("c2", 2)))
        wait_for(lambda: frames_at_m1.where(lambda k, m: m.sensor_id == "c2" and m.seq == 2), 10.0, "c2's 2nd frame")
        assert not wait_for_any(lambda: stolen_at_mz.items or ptz_at["c2"].items, SETTLE_S), (
            stolen_at_mz.items,
            ptz_at["c2"].items,
        )


def msg_replace(msg: Any, **changes: Any) -> Any:
    import msgspec

    return msgspec.structs.replace(msg, **changes)


def test_queries_follow_the_roles(site: SecureSite) -> None:
    """Agents query tracks and ask for PTZ views; a sensor cannot query tracks; the manager reads sensor info."""
    track = _trackset("m1", 5).tracks[0]
    with (
        _tls_client(site, "manager-m1") as mgr,
        _tls_client(site, "sensor-c1") as c1,
        _tls_client(site, "agent-a1") as agent,
    ):

        def on_track(q: Any) -> None:
            with q:
                q.reply(KEYS.track(track.track_id), encode(track))

        def on_ptz(q: Any) -> None:
            with q:
                req = decode(q.payload.to_bytes(), PtzRequest)
                reply = PtzReply(manager_id="m1", seq=1, stamp_ns=1, ok=False, track_id=req.track_id, reason="test")
                q.reply(str(q.key_expr), encode(reply))

        def on_info(q: Any) -> None:
            with q:
                q.reply(KEYS.sensor_info("c1"), b"info")

        qs = [
            mgr.declare_queryable(KEYS.all_tracks, on_track),
            mgr.declare_queryable(KEYS.ptz_requests("m1"), on_ptz),
            c1.declare_queryable(KEYS.sensor_info("c1"), on_info),
        ]

        def get(s: Any, key: str, payload: bytes | None = None) -> list[str]:
            return [str(r.ok.key_expr) for r in s.get(key, payload=payload, timeout=2.0) if r.ok is not None]

        assert wait_for(lambda: get(agent, KEYS.track(track.track_id)), 10.0, "agent gets a track") == [
            KEYS.track(track.track_id)
        ]
        req = PtzRequest(agent_id="a1", seq=1, stamp_ns=1, action="acquire", track_id=track.track_id)
        assert wait_for(lambda: get(agent, KEYS.ptz_request("m1", "a1"), encode(req)), 10.0, "PTZ allocation reply")
        # An agent speaks only for itself: its certificate may not query another agent's PTZ key.
        assert get(agent, KEYS.ptz_request("m1", "a2"), encode(req)) == []
        assert wait_for(lambda: get(mgr, KEYS.all_sensor_info), 10.0, "manager reads sensor info") == [
            KEYS.sensor_info("c1")
        ]
        assert get(c1, KEYS.all_tracks) == []  # denied at the router: no reply at all
        assert get(agent, KEYS.all_features) == []
        for q in qs:
            q.undeclare()


def test_a_sensor_cannot_impersonate_another_sensors_presence(site: SecureSite) -> None:
    with _tls_client(site, "manager-m1") as mgr, _tls_client(site, "sensor-c2") as c2:
        own = c2.liveliness().declare_token(KEYS.sensor("c2"))
        fake = c2.liveliness().declare_token(KEYS.sensor("c1"))

        def alive() -> list[str]:
            return sorted(str(r.ok.key_expr) for r in mgr.liveliness().get(KEYS.all_sensors, timeout=1.0) if r.ok)

        wait_for(lambda: KEYS.sensor("c2") in alive(), 10.0, "c2's own token")
        assert KEYS.sensor("c1") not in alive()
        fake.undeclare()
        own.undeclare()


# ---------------------------------------------------------------------------
# User/password alternative
# ---------------------------------------------------------------------------


def test_usrpwd_variant(site: SecureSite) -> None:
    users = site.users()
    tcp = f"tcp/127.0.0.1:{site.tcp_port}"

    def creds(name: str, password: str | None = None) -> SessionSettings:
        return SessionSettings(
            mode="client",
            connect=[tcp],
            connect_timeout_ms=REFUSE_MS if password is not None else 10_000,
            user=name,
            password=users[name] if password is None else password,
        )

    for bad in (
        creds("sensor-c1", "wrong"),
        SessionSettings(mode="client", connect=[tcp], connect_timeout_ms=REFUSE_MS),
    ):
        with pytest.raises(SessionError), open_session(bad):
            pass
    # A client config file from make_configs.py works as well as [zenoh] user/password.
    mgr_cfg = SessionSettings(mode="client", config_file=str(site.cfg / "usrpwd" / "manager-m1.json5"), connect=[tcp])
    with open_session(mgr_cfg) as mgr, open_session(creds("sensor-c1")) as c1, open_session(creds("agent-a1")) as ag:
        feats = Collector(mgr, KEYS.all_features, Features)
        _deliver_until(
            lambda: c1.put(KEYS.sensor_features("c1"), encode(_features("c1", 1))),
            lambda: feats.where(lambda k, m: m.seq == 1),
            "c1's features over user/password",
        )
        ag.put(KEYS.sensor_features("c1"), encode(_features("c1", 666)))
        c1.put(KEYS.sensor_features("c1"), encode(_features("c1", 2)))
        wait_for(lambda: feats.where(lambda k, m: m.seq == 2), 10.0, "c1's marker")
        assert not wait_for_any(lambda: feats.where(lambda k, m: m.seq == 666), SETTLE_S), feats.items


def test_routers_stay_up(site: SecureSite) -> None:
    """Refused and denied clients never take the routers down."""
    assert site.router.alive, site.router.log()
    assert site.usr_router.alive, site.usr_router.log()


def test_committed_demo_configs_match_the_generator(tmp_path: Path) -> None:
    """deploy/security/demo/ is what make_configs.py writes for the demo site (no hand edits drift)."""
    demo = SECURITY / "demo"
    out = tmp_path / "demo"
    _make_configs("deploy/security/generated", out, "--sensors", "pano1 pano2 pano3 ptz1", "--managers", "mgr1",
                  "--agents", "agent1", "--tls-only")  # fmt: skip
    committed = sorted(p.name for p in demo.glob("*.json5"))
    assert committed == sorted(p.name for p in out.glob("*.json5"))
    for name in committed:
        assert (demo / name).read_text() == (out / name).read_text(), f"{name} differs from the generator's"
    # The demo's processes use exactly these identities.
    from common.site import load_site

    site = load_site(REPO / "deploy" / "sites" / "demo.toml")
    assert {f"sensor-{c.id}.json5" for c in site.camera} <= set(committed)


# ---------------------------------------------------------------------------
# The real processes on the secured network
# ---------------------------------------------------------------------------


def test_real_site_runs_on_tls_and_forged_tracks_never_reach_agents(tmp_path: Path, request: Any) -> None:
    """Router (TLS + ACL), real manager and sensor nodes with their certificates, an agent: tracks flow;
    an agent certificate publishing fake tracks and a sensor certificate publishing another camera's
    features change nothing. Identity is the key's: a sensor publishing, on its own keys, SensorInfo and
    Features that name another sensor is refused and counted, and the other camera's pose does not move.
    A late-joining agent gets every SensorInfo from the publishers' caches (AdvancedSubscriber history)."""
    from tests.integration.test_faults import MANAGER_ID, _up_to_speed, make_fault_site, observing_session, running
    from user_agent.client import AgentClient

    fsite = make_fault_site(tmp_path, prefix="secure")
    certs, cfg = tmp_path / "certs", tmp_path / "cfg"
    ids = " ".join(fsite.ids)
    who = ("--sensors", ids, "--managers", MANAGER_ID, "--agents", "a1")
    _run(["bash", str(SECURITY / "make-certs.sh"), "--out", str(certs), *who])
    _make_configs(certs, cfg, "--prefix", fsite.prefix, *who, "--listen", f"tls/127.0.0.1:{fsite.port}")
    fsite.connect_to = f"tls/localhost:{fsite.port}"
    with running(fsite, request):
        router = fsite._spawn(
            [sys.executable, "-m", "panostereo", "router", "--zenoh-config", str(cfg / "router-tls.json5")], "router"
        )
        wait_for_port(fsite.port, 20.0, proc=router)
        fsite.start_manager(extra=("--zenoh-config", str(cfg / f"manager-{MANAGER_ID}.json5")))
        for sid in fsite.ids:
            fsite.start_node(sid, extra=("--zenoh-config", str(cfg / f"sensor-{sid}.json5")))
        agent_settings = _settings(cfg / "agent-a1.json5", fsite.endpoint)
        with (
            AgentClient(settings=agent_settings, prefix=fsite.prefix, agent_id="a1") as agent,
            open_session(_settings(cfg / "agent-a1.json5", fsite.endpoint)) as rogue_agent,
            open_session(_settings(cfg / f"sensor-{fsite.ids[3]}.json5", fsite.endpoint)) as rogue_sensor,
        ):
            keys = Keys(fsite.prefix)
            forged = Collector(agent.session, keys.tracks(), TrackSet)
            with observing_session(agent.session, fsite) as obs:
                try:
                    _up_to_speed(fsite, obs)
                except AssertionError as err:
                    raise AssertionError(f"{err}\n{fsite.logs()}") from err
                victim, liar = fsite.ids[0], fsite.ids[3]
                t0 = time.monotonic()

                def victim_known() -> tuple[SensorInfo, tuple[float, float, float]] | None:
                    """The victim's SensorInfo as the agent has it, and its pose in the newest manager status (a
                    loaded host may need a moment for either)."""
                    st = obs.status_since(t0)
                    pose = _pose_of(st[-1], victim) if st else None
                    info = next((v.info for v in agent.sensors() if v.sensor_id == victim), None)
                    return (info, pose) if info is not None and pose is not None else None

                real_info, pose_before = wait_for(victim_known, 20.0, "the victim's SensorInfo and its pose")
                moved = msg_replace(real_info, pose=Pose(x_m=0.5, y_m=0.5, z_m=1.0, yaw_rad=0.0), seq=99)
                for i in range(50):
                    rogue_agent.put(keys.tracks(), encode(_trackset(MANAGER_ID, 10**9 + i)))
                    rogue_sensor.put(keys.sensor_features(victim), encode(_features(victim, 10**9 + i)))  # denied
                    # On its own keys (allowed by the rules) but speaking for the victim: refused by the manager.
                    lie = msg_replace(_features(victim, i), stamp_ns=time.time_ns())
                    rogue_sensor.put(keys.sensor_features(liar), encode(lie))
                    rogue_sensor.put(keys.sensor_info(liar), encode(moved))
                    time.sleep(0.02)  # paced: none pushed out of the manager's per-key buffers uncounted
                # The manager goes on (its tick after the forgeries arrives), all four cameras in use.
                wait_for(lambda: obs.tracking_with(t0, set(fsite.ids), min_sets=10), 20.0, "tracks after the forgeries")
                assert not forged.where(lambda k, m: m.seq >= 10**9), "a forged TrackSet reached an agent"
                assert agent.tracks(timeout_s=2.0), "the agent API sees no tracks over TLS"
                assert {v.sensor_id for v in agent.sensors()} >= set(fsite.ids)
                last = wait_for(
                    lambda: next(
                        (st for st in reversed(obs.status_since(t0))
                         if any(r.sender_id == liar and r.wrong_id >= 50 for r in st.refused)),
                        None,
                    ),
                    10.0,
                    f"{liar}'s messages speaking for {victim} refused and counted (50 of 100 at least)",
                )  # fmt: skip
                assert _pose_of(last, victim) == pose_before, "a forged SensorInfo moved another sensor's pose"
                seen = wait_for(
                    lambda: next((v.info for v in agent.sensors() if v.sensor_id == victim and v.info), None),
                    10.0,
                    f"{victim}'s SensorInfo at the agent",
                )
                assert seen == real_info, "a forged SensorInfo reached the agent"
            # A late joiner gets every sensor's SensorInfo from the nodes' publisher caches (no get of its own).
            with AgentClient(settings=agent_settings, prefix=fsite.prefix, agent_id="a1") as late:
                wait_for(lambda: set(late._infos) >= set(fsite.ids), 10.0, "SensorInfo from the caches")
        assert router.alive, router.log()


# ---------------------------------------------------------------------------
# Rotation and revocation (deploy/security/README.md, section 5)
# ---------------------------------------------------------------------------


def _router_with(tmp_path: Path, name: str, conf: dict[str, Any]) -> tuple[ManagedProcess, str]:
    """A TLS router from a config dict on a fresh port; returns it and its endpoint."""
    port = free_port()
    conf["listen"]["endpoints"] = [f"tls/127.0.0.1:{port}"]
    path = tmp_path / f"{name}.json5"
    path.write_text(json.dumps(conf))
    proc = spawn([sys.executable, "-m", "panostereo", "router", "--zenoh-config", str(path)], log_dir=tmp_path,
                 name=name)  # fmt: skip
    wait_for_port(port, 20.0, proc=proc)
    return proc, f"tls/localhost:{port}"


def test_ca_rotation_a_bundle_of_old_and_new_ca_lets_both_generations_in(site: SecureSite, tmp_path: Path) -> None:
    """Rotation: a new CA, every trust point holding old + new CA in one file; certificates of both
    generations connect meanwhile; once the old CA leaves the bundle, its certificates are refused."""
    new = tmp_path / "new"
    _run(["bash", str(SECURITY / "make-certs.sh"), "--out", str(new), "--sensors", "c2", "--ca-name", "site-ca-2"])
    bundle = tmp_path / "ca-bundle.pem"
    bundle.write_text((site.certs / "ca.pem").read_text() + (new / "ca.pem").read_text())
    conf = _json5(site.cfg / "router-tls.json5")
    conf["transport"]["link"]["tls"].update(
        root_ca_certificate=str(bundle),
        listen_certificate=str(new / "router.pem"),
        listen_private_key=str(new / "router.key"),
    )
    router, endpoint = _router_with(tmp_path, "router-rotating", conf)
    old_c1 = _variant(site, tmp_path, "sensor-c1", root_ca_certificate=str(bundle))
    new_pem, new_key = str(new / "sensor-c2.pem"), str(new / "sensor-c2.key")
    new_c2 = _variant(site, tmp_path, "sensor-c2", root_ca_certificate=str(bundle), connect_certificate=new_pem,
                      connect_private_key=new_key)  # fmt: skip
    try:
        for cfg in (old_c1, new_c2):
            with open_session(_settings(cfg, endpoint)) as s:
                assert s.info.routers_zid()
    finally:
        router.stop()
    conf["transport"]["link"]["tls"]["root_ca_certificate"] = str(new / "ca.pem")  # rotation done
    router, endpoint = _router_with(tmp_path, "router-rotated", conf)
    try:
        with pytest.raises(SessionError), open_session(_settings(old_c1, endpoint, timeout_ms=REFUSE_MS)):
            pass
        with open_session(_settings(new_c2, endpoint)) as s:
            assert s.info.routers_zid()
    finally:
        router.stop()


def test_revocation_an_identity_out_of_the_rules_can_do_nothing(site: SecureSite, tmp_path: Path) -> None:
    """Revocation: regenerate the router's config without the identity (its certificate still verifies):
    it connects, and every message of it is denied while the others flow."""
    cfg = tmp_path / "revoked"
    _make_configs(site.certs, cfg, "--prefix", KEYS.prefix, "--sensors", "c1", "--managers", "m1", "--agents", "a1",
                  "--tls-only")  # fmt: skip  # c2 left out
    router, endpoint = _router_with(tmp_path, "router-revoked", _json5(cfg / "router-tls.json5"))
    try:
        with (
            open_session(_settings(site.cfg / "manager-m1.json5", endpoint)) as mgr,
            open_session(_settings(site.cfg / "sensor-c1.json5", endpoint)) as c1,
            open_session(_settings(site.cfg / "sensor-c2.json5", endpoint)) as c2,
        ):
            feats = Collector(mgr, KEYS.all_features, Features)
            _deliver_until(
                lambda: c1.put(KEYS.sensor_features("c1"), encode(_features("c1", 1))),
                lambda: feats.where(lambda k, m: m.seq == 1),
                "c1's features",
            )
            c2.put(KEYS.sensor_features("c2"), encode(_features("c2", 666)))
            c1.put(KEYS.sensor_features("c1"), encode(_features("c1", 2)))
            wait_for(lambda: feats.where(lambda k, m: m.seq == 2), 10.0, "c1's marker")
            assert not wait_for_any(lambda: feats.where(lambda k, m: m.sensor_id == "c2"), SETTLE_S), feats.items
    finally:
        router.stop()


@pytest.mark.parametrize(("agent_id", "warned"), [(None, True), ("a1", False)])
def test_an_agent_told_when_the_router_refuses_its_identity(
    site: SecureSite, agent_id: str | None, warned: bool
) -> None:
    """`agent tracks --zenoh-config agent-a1.json5` without `--agent-id a1` announces itself as agent-<pid>, which
    the rules deny silently: the CLI says so (its PTZ requests would be refused as well)."""
    args = [sys.executable, "-m", "panostereo", "agent", "tracks", "--prefix", KEYS.prefix, "--timeout", "0.2",
            "--zenoh-config", str(site.cfg / "agent-a1.json5"), "--connect", site.tls]  # fmt: skip
    if agent_id:
        args += ["--agent-id", agent_id]
    res = subprocess.run(args, cwd=REPO, capture_output=True, text=True, timeout=60, check=False)
    assert res.returncode == 0, res.stderr
    assert ("did not take this agent's liveliness token" in res.stderr) == warned, res.stderr
