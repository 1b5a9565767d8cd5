"""Keys: each builder gives a concrete key its wildcard includes, that parses back, and that nothing else matches."""

from __future__ import annotations

from collections.abc import Callable

import pytest
import zenoh

from common.errors import ConfigError
from common.keys import DEFAULT_PREFIX, Keys, ParsedKey, validate_id

K = Keys()

# builder, the wildcard (property name) that must include it, the parsed kind.
BUILDERS: list[tuple[str, str, str]] = [
    ("sensor", "all_sensors", "sensor"),
    ("sensor_info", "all_sensor_info", "sensor_info"),
    ("sensor_features", "all_features", "sensor_features"),
    ("sensor_status", "all_sensor_status", "sensor_status"),
    ("sensor_ptz_state", "all_ptz_state", "sensor_ptz_state"),
    ("sensor_ptz", "", "sensor_ptz"),
    ("manager", "all_managers", "manager"),
    ("manager_pairs", "all_pairs", "manager_pairs"),
    ("manager_ptz", "all_manager_ptz", "manager_ptz"),
    ("manager_status", "all_manager_status", "manager_status"),
    ("track", "all_tracks", "track"),
    ("plan", "all_plans", "plan"),
    ("agent", "all_agents", "agent"),
]
WILDCARDS = sorted({w for _, w, _ in BUILDERS if w} | {"all"})


def build(keys: Keys, name: str, ident: str) -> str:
    fn: Callable[[str], str] = getattr(keys, name)
    return fn(ident)


def concrete_keys(keys: Keys, ident: str = "cam-1") -> dict[str, str]:
    out = {name: build(keys, name, ident) for name, _, _ in BUILDERS}
    out["tracks"] = keys.tracks()
    return out


def test_documented_key_strings() -> None:
    """The key table of common/keys.py, spelled out: this is the public API."""
    assert concrete_keys(K, "x1") == {
        "sensor": "pano/@v1/sensor/x1",
        "sensor_info": "pano/@v1/sensor/x1/info",
        "sensor_features": "pano/@v1/sensor/x1/features",
        "sensor_status": "pano/@v1/sensor/x1/status",
        "sensor_ptz_state": "pano/@v1/sensor/x1/ptz/state",
        "sensor_ptz": "pano/@v1/sensor/x1/ptz",
        "manager": "pano/@v1/manager/x1",
        "manager_pairs": "pano/@v1/manager/x1/pairs",
        "manager_ptz": "pano/@v1/manager/x1/ptz",
        "manager_status": "pano/@v1/manager/x1/status",
        "track": "pano/@v1/track/x1",
        "plan": "pano/@v1/plan/x1",
        "agent": "pano/@v1/agent/x1",
        "tracks": "pano/@v1/tracks",
    }
    assert DEFAULT_PREFIX == "pano"
    assert K.root == "pano/@v1"


@pytest.mark.parametrize("prefix", ["pano", "site-a/lab_2", "X"])
@pytest.mark.parametrize(("name", "wildcard", "kind"), BUILDERS)
def test_builder_is_concrete_included_and_parses_back(prefix: str, name: str, wildcard: str, kind: str) -> None:
    keys = Keys(prefix)
    key = build(keys, name, "cam-1")
    ke = zenoh.KeyExpr(key)  # valid key expression
    assert str(ke) == key
    assert not any(c in key for c in "*$?#"), "a builder must give a concrete key"
    assert keys.parse(key) == ParsedKey(kind, "cam-1")  # type: ignore[arg-type]
    assert zenoh.KeyExpr(keys.all).includes(ke)
    if wildcard:
        wild = zenoh.KeyExpr(getattr(keys, wildcard))
        assert wild.includes(ke)
        assert wild.intersects(ke)


@pytest.mark.parametrize("wildcard", WILDCARDS)
def test_each_wildcard_matches_exactly_its_own_keys(wildcard: str) -> None:
    wild = zenoh.KeyExpr(getattr(K, wildcard))
    for ident in ("a", "cam-1"):
        for name, key in concrete_keys(K, ident).items():
            own = wildcard == "all" or any(w == wildcard and b == name for b, w, _ in BUILDERS)
            assert wild.includes(zenoh.KeyExpr(key)) == own, (wildcard, key)
            assert wild.intersects(zenoh.KeyExpr(key)) == own, (wildcard, key)


def test_wildcards_are_pairwise_disjoint_except_all() -> None:
    for a in WILDCARDS:
        for b in WILDCARDS:
            if a == b or "all" in (a, b):
                continue
            assert not zenoh.KeyExpr(getattr(K, a)).intersects(zenoh.KeyExpr(getattr(K, b))), (a, b)


def test_tracks_key_is_not_a_track_key() -> None:
    assert not zenoh.KeyExpr(K.all_tracks).intersects(zenoh.KeyExpr(K.tracks()))
    assert K.parse(K.tracks()) == ParsedKey("tracks", "")


def test_prefixes_do_not_cross_talk() -> None:
    a, b = Keys("site-a"), Keys("site-b")
    assert not zenoh.KeyExpr(a.all).intersects(zenoh.KeyExpr(b.sensor_features("p1")))
    assert not zenoh.KeyExpr(Keys("pano").all).intersects(zenoh.KeyExpr(Keys("pano/x").sensor("p1")))
    with pytest.raises(ConfigError, match="not under"):
        a.parse(b.sensor("p1"))


def test_all_keys_distinct() -> None:
    keys = list(concrete_keys(K).values())
    assert len(set(keys)) == len(keys)


@pytest.mark.parametrize(
    "bad", ["", "Cam1", "cam/1", "cam*", "-cam", "cam 1", "cam_1", "cam$", "cäm", "x" * 49, "cam#1", "cam?"]
)
def test_invalid_ids_are_refused_by_every_builder(bad: str) -> None:
    with pytest.raises(ConfigError, match=r"must match \[a-z0-9\]"):
        validate_id(bad)
    for name, _, _ in BUILDERS:
        with pytest.raises(ConfigError):
            build(K, name, bad)


@pytest.mark.parametrize("good", ["a", "0", "cam-1", "x" * 48, "mgr1-17"])
def test_valid_ids(good: str) -> None:
    assert validate_id(good) == good


def test_validate_id_names_what() -> None:
    with pytest.raises(ConfigError, match=r"sensor id must match .* got 'Bad'"):
        K.sensor("Bad")


@pytest.mark.parametrize("bad", ["", "/pano", "pano/", "pa no", "pano//x", "pano/*", "pano/**", "@v1", "a$b"])
def test_invalid_prefixes(bad: str) -> None:
    with pytest.raises(ConfigError, match="key prefix"):
        Keys(bad)


@pytest.mark.parametrize(
    "key",
    [
        "pano/@v1",
        "pano/@v1/sensor",
        "pano/@v1/sensor/a/unknown",
        "pano/@v1/sensor/a/ptz/other",
        "pano/@v1/tracks/a",
        "pano/@v1/track",
        "pano/@v1/track/A",
        "pano/@v1/manager/a/b/c",
        "pano/@v2/sensor/a",
        "other/@v1/sensor/a",
        "pano/@v1/sensor/*/features",
    ],
)
def test_parse_rejects_undocumented_keys(key: str) -> None:
    with pytest.raises(ConfigError):
        K.parse(key)


def test_zone_seat_keys_parse_back_and_sit_under_their_managers_key() -> None:
    """A zone's seats: each under its manager's own key (what its certificate may declare), one wildcard per zone."""
    lead, stand = K.zone_leader("mgr-a", "hall", 3), K.zone_standby("mgr-b", "hall")
    assert lead == "pano/@v1/manager/mgr-a/zone/hall/leader/3"
    assert stand == "pano/@v1/manager/mgr-b/zone/hall/standby"
    assert K.parse(lead) == ParsedKey("zone_leader", "mgr-a", "hall", 3)
    assert K.parse(stand) == ParsedKey("zone_standby", "mgr-b", "hall")
    seats = zenoh.KeyExpr(K.zone_seats("hall"))
    assert seats.includes(zenoh.KeyExpr(lead)) and seats.includes(zenoh.KeyExpr(stand))
    assert not seats.intersects(zenoh.KeyExpr(K.zone_standby("mgr-b", "yard")))
    for wild in WILDCARDS:  # no other wildcard hears a seat: agents listing managers see no seat as a manager
        if wild != "all":
            assert not zenoh.KeyExpr(getattr(K, wild)).intersects(zenoh.KeyExpr(lead)), wild


@pytest.mark.parametrize("term", [0, -1, True, 1.5])
def test_a_leader_term_is_a_positive_integer(term: object) -> None:
    with pytest.raises(ConfigError, match="term is a positive integer"):
        K.zone_leader("m", "z", term)  # type: ignore[arg-type]


@pytest.mark.parametrize("tail", ["leader/0", "leader/x", "leader/-1", "leader/" + "9" * 19])
def test_a_seat_key_with_a_bad_term_is_refused(tail: str) -> None:
    with pytest.raises(ConfigError, match="term is a positive integer"):
        K.parse(f"pano/@v1/manager/m/zone/z/{tail}")


def test_a_bad_zone_is_refused() -> None:
    with pytest.raises(ConfigError, match="zone must match"):
        K.zone_seats("Hall")
