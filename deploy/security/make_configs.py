#!/usr/bin/env python3
"""Zenoh configs for a secured panostereo site: TLS + mutual TLS + access control, or user/password.

Usage::

    python3 deploy/security/make_configs.py --certs DIR --out DIR [--prefix pano] \
        [--sensors "c1 c2"] [--managers "m1 mgr-nw=c1,c2"] [--agents "a1 ops:10"] [--listen tls/0.0.0.0:7447] \
        [--router-host localhost] [--users-only]

Reads nothing but the command line (the certificates come from ``make-certs.sh``; only
their paths are written) and writes, under ``--out``:

* ``router-tls.json5``: the router. TLS only (``protocols: ["tls"]``), ``enable_mtls``, so a
  client must present a certificate signed by the site CA; default-deny access control
  whose subjects are the certificates' common names.
* ``sensor-<id>.json5``, ``manager-<id>.json5``, ``agent-<id>.json5``: each client's TLS
  config (its own certificate and key, the CA, ``enable_mtls: true``: without it a client
  sends no certificate at all).
* ``router-usrpwd.json5`` + ``users.txt`` and ``usrpwd/<name>.json5``: the alternative with
  no certificates: user/password authentication on TCP and the same rules, whose subjects
  are user names. Passwords are random; ``users.txt`` is the router's dictionary, named in
  the router's config under ``--certs`` (where the router's files are deployed); it listens
  on ``--listen-tcp`` (default: ``--listen``'s host, the next port). Every file holding a
  password is created mode 600.
* ``ptz-priorities.toml``: the ``[ptz.max_priority]`` table for every manager's config: an
  agent written ``ops:10`` in ``--agents`` gets PTZ priority at most 10, the others the
  manager's ``[ptz] default_max_priority`` (0: all equal). Priority comes from identity: the
  manager answers an agent only on ``R/manager/<mid>/ptz/<id>``, which the rules below let
  that agent's certificate alone query, and clips every request to its cap.

Only the ids named are written: nothing is assumed (adding a camera is this same command with
the camera added to ``--sensors``).

The rules (one rule + subject + policy per identity, so an identity can only speak for
itself; key expressions from ``common/keys.py``, ``R = {prefix}/@v1``):

sensor ``<id>``
    put ``R/sensor/<id>/features|info|status|ptz/state``; declare its liveliness token
    ``R/sensor/<id>`` and its info queryable (and reply on it), and the cache of its SensorInfo
    publisher (``R/sensor/<id>/info/@adv/**``: a queryable and a liveliness token, zenoh.ext);
    subscribe to its own PTZ commands and the view plans (``R/plan/*``: a simulated node needs
    every robot's goal); see managers' presence, and its own (a second process under its id is refused).
manager ``<id>``
    declare its presence ``R/manager/<id>`` and its zone seat ``R/manager/<id>/zone/**`` (a standby's
    or a leader's token, resource_manager/serve/election.py); put ``R/tracks``, ``R/track/*``,
    ``R/plan/*``, ``R/manager/<id>/**`` and PTZ commands ``R/sensor/*/ptz``; serve ``R/track/**``
    and ``R/manager/<id>/**`` queryables (PTZ requests arrive on ``R/manager/<id>/ptz/<agent>``);
    read every sensor key, query sensor info and the SensorInfo publishers' caches.
    A manager written ``<id>=c1,c2`` (a zone's manager, and its standby) reads, queries, plans for and
    commands the sensors ``c1``, ``c2`` only: a zone manager taken over cannot see or move the
    other zones' cameras. The TrackSets of every manager share one key, ``R/tracks``.
agent ``<id>``
    no put at all; subscribe to tracks, plans, pairs, statuses and PTZ states (not raw
    features); query tracks, sensor info (and its publishers' caches) and PTZ views on its own
    key only, ``R/manager/*/ptz/<id>``: it cannot speak for another agent; its liveliness token
    ``R/agent/<id>``.

Anything not allowed is denied; a denied put is dropped silently at the router.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import secrets
import sys
from pathlib import Path
from typing import Any

ID_RE = re.compile(r"^[a-z0-9][a-z0-9-]*$")
MAX_ID_LEN = 48
"""Longest id, as common.schema.MAX_ID_LEN (this script runs without the package installed)."""
MAX_PRIORITY = 1000
"""Highest PTZ priority, as common.schema.Priority."""
PREFIX_RE = re.compile(r"^[A-Za-z0-9_-]+(/[A-Za-z0-9_-]+)*$")

Rule = dict[str, Any]


def info_caches(root: str) -> str:
    """Where zenoh.ext keeps every sensor's SensorInfo publisher cache and presence token.

    ``**`` never matches a chunk starting with ``@``: ``R/sensor/**`` does not cover these.
    """
    return f"{root}/sensor/*/info/@adv/**"


def cache_reader_rules(root: str, n: str, cameras: list[str] | None = None) -> list[Rule]:
    """What an AdvancedSubscriber of SensorInfo needs: query the caches, see their publishers come and go (of
    ``cameras`` only, if given)."""
    caches = [f"{root}/sensor/{c}/info/@adv/**" for c in cameras] if cameras is not None else [info_caches(root)]
    return [
        _rule(f"{n}-cache-query", "ingress", ["query", "declare_liveliness_subscriber", "liveliness_query"], caches),
        _rule(f"{n}-cache-replies", "egress", ["reply", "declare_queryable", "liveliness_token"], caches),
    ]


def _rule(rid: str, flow: str, messages: list[str], keys: list[str]) -> Rule:
    return {"id": rid, "permission": "allow", "flows": [flow], "messages": messages, "key_exprs": keys}


def sensor_rules(root: str, sid: str) -> list[Rule]:
    """What sensor ``sid`` may do (ingress: sensor -> router; egress: router -> sensor)."""
    own = f"{root}/sensor/{sid}"
    n = f"sensor-{sid}"
    outputs = [f"{own}/features", f"{own}/info", f"{own}/status", f"{own}/ptz/state"]
    return [
        _rule(f"{n}-put", "ingress", ["put"], outputs),
        # A declared publisher sends only while it knows of a matching subscriber (write-side
        # filtering), so it must see the declarations of the subscribers to its keys. Those are
        # wildcards (the manager subscribes to R/sensor/*/features): the rule must include them.
        _rule(f"{n}-subscribers", "egress", ["declare_subscriber"], [f"{root}/sensor/**"]),
        _rule(f"{n}-token", "ingress", ["liveliness_token"], [own]),
        _rule(f"{n}-serve", "ingress", ["declare_queryable", "reply"], [f"{own}/info", f"{own}/info/@adv/**"]),
        _rule(f"{n}-cache-token", "ingress", ["liveliness_token"], [f"{own}/info/@adv/**"]),
        _rule(f"{n}-cache-queried", "egress", ["query"], [info_caches(root)]),
        # Plans of every camera: a simulated node replays every robot's goals to render the same world.
        _rule(f"{n}-sub", "ingress", ["declare_subscriber"], [f"{own}/ptz", f"{root}/plan/*"]),
        # Managers' presence; and its own, which it asks for before it starts (one process per id).
        _rule(
            f"{n}-watch",
            "ingress",
            ["declare_liveliness_subscriber", "liveliness_query"],
            [f"{root}/manager/*", own],
        ),
        _rule(f"{n}-recv", "egress", ["put"], [f"{own}/ptz", f"{root}/plan/*"]),
        # A query for every sensor's info (``R/sensor/*/info``) must reach this sensor too.
        _rule(f"{n}-queried", "egress", ["query"], [f"{root}/sensor/*/info"]),
        _rule(f"{n}-seen", "egress", ["liveliness_token"], [f"{root}/manager/*", own]),
    ]


def manager_rules(root: str, mid: str, cameras: list[str] | None = None) -> list[Rule]:
    """What manager ``mid`` may do; with ``cameras`` (a zone manager's), read, query and command those sensors only."""
    own = f"{root}/manager/{mid}"
    n = f"manager-{mid}"
    sensors = [f"{root}/sensor/{c}" for c in cameras] if cameras is not None else [f"{root}/sensor/*"]
    plans = [f"{root}/plan/{c}" for c in cameras] if cameras is not None else [f"{root}/plan/*"]
    commands = [f"{s}/ptz" for s in sensors]
    infos = [f"{s}/info" for s in sensors]
    outputs = [f"{root}/tracks", f"{root}/track/**", *plans, f"{own}/**", *commands]
    served = [f"{root}/tracks", f"{root}/track/**", f"{own}/**"]
    sensor_keys = [f"{s}/**" for s in sensors] if cameras is not None else [f"{root}/sensor/**"]
    read = [*sensor_keys, f"{root}/manager/**", f"{root}/plan/*", f"{root}/tracks", f"{root}/track/**"]
    return [
        _rule(f"{n}-put", "ingress", ["put", "delete"], outputs),
        _rule(
            f"{n}-subscribers",
            "egress",
            ["declare_subscriber"],
            [f"{root}/tracks", f"{root}/track/**", f"{root}/plan/**", f"{root}/manager/**", *commands],
        ),
        # Its presence, and its seat in its zone (leader or standby): under its own key only.
        _rule(f"{n}-token", "ingress", ["liveliness_token"], [own, f"{own}/zone/**"]),
        _rule(f"{n}-serve", "ingress", ["declare_queryable", "reply"], served),
        _rule(f"{n}-queryables", "egress", ["declare_queryable"], [*infos, f"{root}/track/**"]),
        _rule(f"{n}-sub", "ingress", ["declare_subscriber"], read),
        _rule(f"{n}-query", "ingress", ["query"], [*infos, f"{root}/track/**"]),
        _rule(f"{n}-watch", "ingress", ["declare_liveliness_subscriber", "liveliness_query"], [f"{root}/**"]),
        _rule(f"{n}-recv", "egress", ["put", "delete"], read),
        _rule(f"{n}-queried", "egress", ["query"], served),
        _rule(f"{n}-replies", "egress", ["reply"], [*infos, f"{root}/track/**"]),
        _rule(f"{n}-seen", "egress", ["liveliness_token"], [f"{root}/**"]),
        *cache_reader_rules(root, n, cameras),
    ]


def agent_rules(root: str, aid: str) -> list[Rule]:
    """What agent ``aid`` may do: read derived data and query, never put."""
    n = f"agent-{aid}"
    read = [
        f"{root}/tracks",
        f"{root}/track/**",
        f"{root}/plan/*",
        f"{root}/manager/*/pairs",
        f"{root}/manager/*/status",
        f"{root}/sensor/*/status",
        f"{root}/sensor/*/ptz/state",
    ]
    queries = [f"{root}/tracks", f"{root}/track/**", f"{root}/sensor/*/info", f"{root}/manager/*/ptz/{aid}"]
    return [
        _rule(f"{n}-sub", "ingress", ["declare_subscriber"], read),
        _rule(f"{n}-query", "ingress", ["query"], queries),
        _rule(f"{n}-queryables", "egress", ["declare_queryable"], queries),
        _rule(f"{n}-token", "ingress", ["liveliness_token"], [f"{root}/agent/{aid}"]),
        _rule(f"{n}-watch", "ingress", ["declare_liveliness_subscriber", "liveliness_query"], [f"{root}/**"]),
        _rule(f"{n}-recv", "egress", ["put", "delete"], read),
        _rule(f"{n}-replies", "egress", ["reply"], queries),
        _rule(f"{n}-seen", "egress", ["liveliness_token"], [f"{root}/**"]),
        *cache_reader_rules(root, n),
    ]


def access_control(root: str, identities: list[tuple[str, list[Rule]]], by: str) -> dict[str, Any]:
    """Default-deny ACL: each identity (certificate CN or user name) gets exactly its rules."""
    rules: list[Rule] = []
    subjects: list[dict[str, Any]] = []
    policies: list[dict[str, Any]] = []
    for name, its_rules in identities:
        rules.extend(its_rules)
        subjects.append({"id": name, by: [name]})
        policies.append({"id": name, "rules": [r["id"] for r in its_rules], "subjects": [name]})
    return {
        "enabled": True,
        "default_permission": "deny",
        "rules": rules,
        "subjects": subjects,
        "policies": policies,
    }


def identities(
    root: str, sensors: list[str], managers: list[str], agents: list[str], cameras: dict[str, list[str]] | None = None
) -> list[tuple[str, list[Rule]]]:
    """Every identity's rules; ``cameras``: manager id -> the only sensors it may read and command (a zone's)."""
    cameras = cameras or {}
    out: list[tuple[str, list[Rule]]] = []
    out += [(f"sensor-{s}", sensor_rules(root, s)) for s in sensors]
    out += [(f"manager-{m}", manager_rules(root, m, cameras.get(m))) for m in managers]
    out += [(f"agent-{a}", agent_rules(root, a)) for a in agents]
    return out


def _base(mode: str, listen: list[str], connect: list[str]) -> dict[str, Any]:
    return {
        "mode": mode,
        "listen": {"endpoints": listen},
        "connect": {"endpoints": connect},
        "scouting": {"multicast": {"enabled": False}, "gossip": {"enabled": False}},
    }


def router_tls(certs: str, listen: str, acl: dict[str, Any]) -> dict[str, Any]:
    c = _base("router", [listen], [])
    c["transport"] = {
        "link": {
            "protocols": ["tls"],
            "tls": {
                "root_ca_certificate": f"{certs}/ca.pem",
                "listen_certificate": f"{certs}/router.pem",
                "listen_private_key": f"{certs}/router.key",
                "enable_mtls": True,
            },
        }
    }
    c["access_control"] = acl
    return c


def client_tls(certs: str, name: str, connect: str) -> dict[str, Any]:
    c = _base("client", [], [connect])
    c["transport"] = {
        "link": {
            "tls": {
                "root_ca_certificate": f"{certs}/ca.pem",
                "connect_certificate": f"{certs}/{name}.pem",
                "connect_private_key": f"{certs}/{name}.key",
                "enable_mtls": True,
            }
        }
    }
    return c


def router_usrpwd(certs: str, listen: str, acl: dict[str, Any], password: str) -> dict[str, Any]:
    """The dictionary is named where the router's files are deployed (``--certs``), beside its config."""
    c = _base("router", [listen], [])
    c["transport"] = {
        "link": {"protocols": ["tcp"]},
        "auth": {"usrpwd": {"user": "router", "password": password, "dictionary_file": f"{certs}/users.txt"}},
    }
    c["access_control"] = acl
    return c


def client_usrpwd(name: str, password: str, connect: str) -> dict[str, Any]:
    c = _base("client", [], [connect])
    c["transport"] = {"auth": {"usrpwd": {"user": name, "password": password}}}
    return c


def _manager_cameras(text: str) -> tuple[list[str], dict[str, list[str]]]:
    """``"m1 mgr-nw=c1,c2"`` -> (["m1", "mgr-nw"], {"mgr-nw": ["c1", "c2"]}): manager ids, each with an optional
    list of the only cameras it may read and command (a zone manager's: ``panostereo manager ... --zone Z
    --print-sensors``)."""
    ids: list[str] = []
    cameras: dict[str, list[str]] = {}
    for item in text.split():
        mid, sep, cams = item.partition("=")
        ids.append(mid)
        if sep:
            listed = _ids(cams.replace(",", " "), "camera")
            if not listed:
                raise SystemExit(f"make_configs.py: error: manager {mid!r}: no camera after '=' (id=cam1,cam2)")
            cameras[mid] = listed
    return _ids(" ".join(ids), "manager"), cameras


def _agent_caps(text: str) -> tuple[list[str], dict[str, int]]:
    """``"a1 ops:10"`` -> (["a1", "ops"], {"ops": 10}): agent ids, each with an optional PTZ priority cap."""
    ids: list[str] = []
    caps: dict[str, int] = {}
    for item in text.split():
        aid, sep, cap = item.partition(":")
        ids.append(aid)
        if sep:
            if not cap.isdigit() or int(cap) > MAX_PRIORITY:
                raise SystemExit(
                    f"make_configs.py: error: an agent's PTZ priority cap (id:cap) must be 0..{MAX_PRIORITY},"
                    f" got {item!r}"
                )
            caps[aid] = int(cap)
    return _ids(" ".join(ids), "agent"), caps


def ptz_priorities(caps: dict[str, int]) -> str:
    """The manager config's ``[ptz.max_priority]`` table."""
    lines = [
        "# [ptz.max_priority] for every manager's config: PTZ priority by identity (deploy/security/make_configs.py).",
        "# Requests above an agent's cap are clipped to it; agents not listed get [ptz] default_max_priority.",
        "[ptz.max_priority]",
        *(f"{aid} = {cap}" for aid, cap in sorted(caps.items())),
    ]
    return "\n".join(lines) + "\n"


def _ids(text: str, what: str) -> list[str]:
    ids = text.split()
    for i in ids:
        if len(i) > MAX_ID_LEN or not ID_RE.match(i):
            raise SystemExit(f"make_configs.py: error: {what} ids must match [a-z0-9][a-z0-9-]*, got {i!r}")
    return ids


def _write(path: Path, obj: dict[str, Any], header: str, secret: bool = False) -> None:
    text = (
        f"// {header}\n// Generated by deploy/security/make_configs.py; see deploy/security/README.md.\n"
        + json.dumps(obj, indent=2)
        + "\n"
    )
    _write_text(path, text, secret)


def _write_text(path: Path, text: str, secret: bool) -> None:
    """Write a file; a secret one is created mode 600 (never readable by others, not even for a moment)."""
    if not secret:
        path.write_text(text)
        return
    path.unlink(missing_ok=True)
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    with os.fdopen(fd, "w") as fh:
        fh.write(text)


def _tcp_listen(tls_listen: str) -> str:
    """The user/password router's default endpoint: the TLS one's host, the next port, over tcp."""
    rest = tls_listen.split("/", 1)[-1]
    host, _, port = rest.rpartition(":")
    if not port.isdigit() or not host:
        raise SystemExit(f"make_configs.py: error: --listen must be PROTO/HOST:PORT, got {tls_listen!r}")
    return f"tcp/{host}:{int(port) + 1}"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="make_configs.py", description=__doc__.split("\n\n")[0])
    p.add_argument("--certs", required=True, help="directory of make-certs.sh output (paths are written as given)")
    p.add_argument("--out", required=True, help="directory to write the configs to")
    p.add_argument("--prefix", default="pano", help="site key prefix (default pano)")
    p.add_argument("--sensors", default="", help='sensor ids, space separated ("c1 c2")')
    p.add_argument(
        "--managers",
        default="",
        help='manager ids, each with the only cameras it may read and command if it fuses a zone ("m1 mgr-nw=c1,c2")',
    )
    p.add_argument("--agents", default="", help='agent ids, each with an optional PTZ priority cap ("a1 ops:10")')
    p.add_argument("--listen", default="tls/127.0.0.1:7447", help="router TLS endpoint")
    p.add_argument(
        "--listen-tcp",
        default=None,
        help="router endpoint of the usrpwd variant (default: --listen's host, the next port, tcp)",
    )
    p.add_argument("--router-host", default="localhost", help="name clients connect to (must be in the SAN)")
    p.add_argument("--tls-only", action="store_true", help="skip the user/password variant (no secrets written)")
    args = p.parse_args(argv)
    if not PREFIX_RE.match(args.prefix):
        raise SystemExit(f"make_configs.py: error: --prefix must be chunks of [A-Za-z0-9_-], got {args.prefix!r}")
    root = f"{args.prefix}/@v1"
    sensors = _ids(args.sensors, "sensor")
    managers, cameras = _manager_cameras(args.managers)
    unknown = sorted({c for cams in cameras.values() for c in cams} - set(sensors)) if sensors else []
    if unknown:
        raise SystemExit(f"make_configs.py: error: --managers names cameras not in --sensors: {', '.join(unknown)}")
    agents, caps = _agent_caps(args.agents)
    certs = args.certs.rstrip("/") or "/"
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    port = args.listen.rsplit(":", 1)[-1]
    listen_tcp = args.listen_tcp or _tcp_listen(args.listen)
    tcp_port = listen_tcp.rsplit(":", 1)[-1]
    who = identities(root, sensors, managers, agents, cameras)
    (out / "ptz-priorities.toml").write_text(ptz_priorities(caps))

    _write(
        out / "router-tls.json5",
        router_tls(certs, args.listen, access_control(root, who, "cert_common_names")),
        f"panostereo router: TLS + mutual TLS + default-deny ACL for prefix {args.prefix}",
    )
    for name, _ in who:
        _write(
            out / f"{name}.json5",
            client_tls(certs, name, f"tls/{args.router_host}:{port}"),
            f"panostereo client {name}: TLS with its own certificate (mutual TLS)",
        )

    if args.tls_only:
        print(f"make_configs.py: wrote router-tls.json5, ptz-priorities.toml and {len(who)} client configs in {out}")
        return 0
    passwords = {name: secrets.token_urlsafe(18) for name, _ in who}
    router_pw = secrets.token_urlsafe(18)
    (out / "usrpwd").mkdir(exist_ok=True)
    _write_text(out / "users.txt", "".join(f"{n}:{pw}\n" for n, pw in passwords.items()), secret=True)
    _write(
        out / "router-usrpwd.json5",
        router_usrpwd(certs, listen_tcp, access_control(root, who, "usernames"), router_pw),
        f"panostereo router: user/password + default-deny ACL for prefix {args.prefix} (no TLS); "
        f"its dictionary: {certs}/users.txt",
        secret=True,
    )
    for name, pw in passwords.items():
        f = out / "usrpwd" / f"{name}.json5"
        _write(
            f,
            client_usrpwd(name, pw, f"tcp/{args.router_host}:{tcp_port}"),
            f"panostereo client {name}: user/password",
            secret=True,
        )
    print(
        f"make_configs.py: wrote router-tls.json5, router-usrpwd.json5, users.txt, ptz-priorities.toml and"
        f" {len(who)} client configs"
        f" in {out}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
