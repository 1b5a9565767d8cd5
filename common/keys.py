"""Every key expression of the public API; nowhere else forms key strings.

Root: ``{prefix}/@v1`` (prefix configurable per site, default ``pano``).

=====================================  ===========================  ==============
key                                    kind                         payload
=====================================  ===========================  ==============
``{root}/sensor/{id}``                 liveliness token             presence
``{root}/sensor/{id}/info``            queryable + put on change    SensorInfo
``{root}/sensor/{id}/features``        put per frame                Features
``{root}/sensor/{id}/status``          put 1 Hz                     NodeStatus
``{root}/sensor/{id}/ptz``             subscriber on the node       PtzCommand
``{root}/sensor/{id}/ptz/state``       put on change                PtzState
``{root}/manager/{id}``                liveliness token             presence
``{root}/tracks``                      put per fusion tick          TrackSet
``{root}/track/{track_id}``            queryable (no put)           Track
``{root}/plan/{sensor_id}``            put                          ViewPlan
``{root}/manager/{id}/pairs``          put per tick                 PairChoice
``{root}/manager/{id}/ptz/{agent}``    queryable                    PtzRequest -> PtzReply
``{root}/manager/{id}/ptz``            queryable (superseded)       an error naming the key above
``{root}/manager/{id}/status``         put 1 Hz                     ManagerStatus
``{root}/manager/{id}/zone/{z}/...``   liveliness token             its seat in zone z:
                                                                    ``leader/{term}`` or ``standby``
``{root}/agent/{id}``                  liveliness token             presence
=====================================  ===========================  ==============

``get {root}/track/{track_id}`` answers the latest Track;
``get {root}/track/{track_id}?history=SECONDS`` answers the path as one Track
reply per state, oldest first.

A PTZ request names its agent twice, in the key and in ``PtzRequest.agent_id``:
the manager refuses one where they differ, and a secure site's access rules
let each agent's certificate query only its own ``ptz/{agent}`` key.

The managers of one zone (``[manager] zone``) each hold one seat token under
their own key: ``leader/{term}`` while publishing, ``standby`` while silent
(resource_manager/serve/election.py). ``get`` or a liveliness subscriber on
:meth:`Keys.zone_seats` sees every manager of the zone and its role.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Final, Literal

from common.errors import ConfigError

__all__ = ["DEFAULT_PREFIX", "VERSION", "KeyKind", "Keys", "ParsedKey", "validate_id"]

DEFAULT_PREFIX: Final = "pano"
VERSION: Final = "@v1"

_ID_RE: Final = re.compile(r"^[a-z0-9][a-z0-9-]*$")
_PREFIX_RE: Final = re.compile(r"^[A-Za-z0-9_-]+(/[A-Za-z0-9_-]+)*$")
_MAX_ID_LEN: Final = 48
_MAX_TERM_DIGITS: Final = 18

KeyKind = Literal[
    "sensor",
    "sensor_info",
    "sensor_features",
    "sensor_status",
    "sensor_ptz",
    "sensor_ptz_state",
    "manager",
    "manager_pairs",
    "manager_ptz",
    "ptz_request",
    "manager_status",
    "zone_leader",
    "zone_standby",
    "tracks",
    "track",
    "plan",
    "agent",
]


def validate_id(value: str, what: str = "id") -> str:
    """Return ``value`` if it is a valid id (``[a-z0-9][a-z0-9-]*``, ≤ 48 chars).

    Raises:
        ConfigError: naming ``what`` and the offending value.
    """
    if not isinstance(value, str) or len(value) > _MAX_ID_LEN or not _ID_RE.match(value):
        raise ConfigError(
            f"{what} must match [a-z0-9][a-z0-9-]* and be at most {_MAX_ID_LEN} characters, got {value!r}"
        )
    return value


@dataclass(frozen=True, slots=True)
class ParsedKey:
    """A concrete key taken apart."""

    kind: KeyKind
    ident: str = ""
    """The sensor, manager, agent or track id the key is about ("" for ``tracks``); for ``ptz_request``, the
    agent that speaks."""
    parent: str = ""
    """The manager a ``ptz_request`` key is addressed to; the zone of a ``zone_leader`` or ``zone_standby`` seat
    ("" for every other kind)."""
    term: int = 0
    """The leader's term of a ``zone_leader`` seat (0 for every other kind)."""


@dataclass(frozen=True, slots=True)
class Keys:
    """Key builders, wildcards and the parser for one prefix."""

    prefix: str = DEFAULT_PREFIX

    def __post_init__(self) -> None:
        if not _PREFIX_RE.match(self.prefix):
            raise ConfigError(f"key prefix must be chunks of [A-Za-z0-9_-] separated by '/', got {self.prefix!r}")

    @property
    def root(self) -> str:
        """``{prefix}/@v1``."""
        return f"{self.prefix}/{VERSION}"

    # -- builders ---------------------------------------------------------
    def sensor(self, sensor_id: str) -> str:
        """Liveliness token of a sensor node."""
        return f"{self.root}/sensor/{validate_id(sensor_id, 'sensor id')}"

    def sensor_info(self, sensor_id: str) -> str:
        return f"{self.sensor(sensor_id)}/info"

    def sensor_features(self, sensor_id: str) -> str:
        return f"{self.sensor(sensor_id)}/features"

    def sensor_status(self, sensor_id: str) -> str:
        return f"{self.sensor(sensor_id)}/status"

    def sensor_ptz(self, sensor_id: str) -> str:
        return f"{self.sensor(sensor_id)}/ptz"

    def sensor_ptz_state(self, sensor_id: str) -> str:
        return f"{self.sensor(sensor_id)}/ptz/state"

    def manager(self, manager_id: str) -> str:
        """Liveliness token of a resource manager."""
        return f"{self.root}/manager/{validate_id(manager_id, 'manager id')}"

    def manager_pairs(self, manager_id: str) -> str:
        return f"{self.manager(manager_id)}/pairs"

    def manager_ptz(self, manager_id: str) -> str:
        return f"{self.manager(manager_id)}/ptz"

    def ptz_request(self, manager_id: str, agent_id: str) -> str:
        """Where agent ``agent_id`` asks manager ``manager_id`` for PTZ views: the agent is in the key, so
        the access rules can let each agent speak only for itself."""
        return f"{self.manager_ptz(manager_id)}/{validate_id(agent_id, 'agent id')}"

    def ptz_requests(self, manager_id: str) -> str:
        """Every agent's PTZ requests to one manager (the manager's queryable)."""
        return f"{self.manager_ptz(manager_id)}/*"

    def manager_status(self, manager_id: str) -> str:
        return f"{self.manager(manager_id)}/status"

    def zone_seat(self, manager_id: str, zone: str) -> str:
        """Where manager ``manager_id`` holds its seat in ``zone`` (the prefix of its leader or standby token)."""
        return f"{self.manager(manager_id)}/zone/{validate_id(zone, 'zone')}"

    def zone_leader(self, manager_id: str, zone: str, term: int) -> str:
        """Liveliness token of the zone's leader in its ``term`` (a positive integer)."""
        if not isinstance(term, int) or isinstance(term, bool) or term < 1:
            raise ConfigError(f"a leader's term is a positive integer, got {term!r}")
        return f"{self.zone_seat(manager_id, zone)}/leader/{term}"

    def zone_standby(self, manager_id: str, zone: str) -> str:
        """Liveliness token of a standby manager of the zone."""
        return f"{self.zone_seat(manager_id, zone)}/standby"

    def zone_seats(self, zone: str) -> str:
        """Every seat token of one zone (all its managers, leader and standbys)."""
        return f"{self.root}/manager/*/zone/{validate_id(zone, 'zone')}/**"

    def tracks(self) -> str:
        return f"{self.root}/tracks"

    def track(self, track_id: str) -> str:
        return f"{self.root}/track/{validate_id(track_id, 'track id')}"

    def plan(self, sensor_id: str) -> str:
        return f"{self.root}/plan/{validate_id(sensor_id, 'sensor id')}"

    def agent(self, agent_id: str) -> str:
        """Liveliness token of a user agent."""
        return f"{self.root}/agent/{validate_id(agent_id, 'agent id')}"

    # -- wildcards --------------------------------------------------------
    @property
    def all(self) -> str:
        """Everything of this version: ``{root}/**``."""
        return f"{self.root}/**"

    @property
    def all_sensors(self) -> str:
        """Liveliness of every sensor."""
        return f"{self.root}/sensor/*"

    @property
    def all_sensor_info(self) -> str:
        return f"{self.root}/sensor/*/info"

    @property
    def all_features(self) -> str:
        return f"{self.root}/sensor/*/features"

    @property
    def all_sensor_status(self) -> str:
        return f"{self.root}/sensor/*/status"

    @property
    def all_ptz_state(self) -> str:
        return f"{self.root}/sensor/*/ptz/state"

    @property
    def all_managers(self) -> str:
        """Liveliness of every manager."""
        return f"{self.root}/manager/*"

    @property
    def all_manager_status(self) -> str:
        return f"{self.root}/manager/*/status"

    @property
    def all_pairs(self) -> str:
        return f"{self.root}/manager/*/pairs"

    @property
    def all_manager_ptz(self) -> str:
        return f"{self.root}/manager/*/ptz"

    @property
    def all_ptz_requests(self) -> str:
        return f"{self.root}/manager/*/ptz/*"

    @property
    def all_tracks(self) -> str:
        """Every single-track key (queryable only: the tracks are put on ``tracks``)."""
        return f"{self.root}/track/*"

    @property
    def all_plans(self) -> str:
        return f"{self.root}/plan/*"

    @property
    def all_agents(self) -> str:
        return f"{self.root}/agent/*"

    # -- parser -----------------------------------------------------------
    def parse(self, key: str) -> ParsedKey:
        """Take a concrete key of this prefix apart.

        Raises:
            ConfigError: if the key is not one of the documented keys.
        """
        head = self.root + "/"
        if not key.startswith(head):
            raise ConfigError(f"key {key!r} is not under {self.root!r}")
        parts = key[len(head) :].split("/")
        kind = next((k for shape, k in _KEY_SHAPES if _fits(shape, parts)), None)
        if kind == "ptz_request":
            mid, aid = parts[1], parts[3]
            validate_id(mid, f"manager id in key {key!r}")
            return ParsedKey(kind="ptz_request", ident=validate_id(aid, f"id in key {key!r}"), parent=mid)
        if kind in ("zone_leader", "zone_standby"):
            return _seat(key, kind, parts)
        ident = parts[1] if len(parts) > 1 else ""
        if kind is None:
            raise ConfigError(f"key {key!r} is not a documented panostereo key")
        if ident:
            validate_id(ident, f"id in key {key!r}")
        return ParsedKey(kind=kind, ident=ident)


_KEY_SHAPES: tuple[tuple[tuple[str, ...], KeyKind], ...] = (
    (("tracks",), "tracks"),
    (("track", "*"), "track"),
    (("plan", "*"), "plan"),
    (("agent", "*"), "agent"),
    (("sensor", "*"), "sensor"),
    (("sensor", "*", "info"), "sensor_info"),
    (("sensor", "*", "features"), "sensor_features"),
    (("sensor", "*", "status"), "sensor_status"),
    (("sensor", "*", "ptz"), "sensor_ptz"),
    (("sensor", "*", "ptz", "state"), "sensor_ptz_state"),
    (("manager", "*"), "manager"),
    (("manager", "*", "pairs"), "manager_pairs"),
    (("manager", "*", "ptz"), "manager_ptz"),
    (("manager", "*", "status"), "manager_status"),
    (("manager", "*", "ptz", "*"), "ptz_request"),
    (("manager", "*", "zone", "*", "leader", "*"), "zone_leader"),
    (("manager", "*", "zone", "*", "standby"), "zone_standby"),
)
"""The documented keys below the root, ``*`` for an id (the second part: the sensor's, manager's, ...)."""


def _fits(shape: tuple[str, ...], parts: list[str]) -> bool:
    return len(shape) == len(parts) and all(s in ("*", p) for s, p in zip(shape, parts, strict=True))


def _seat(key: str, kind: KeyKind, parts: list[str]) -> ParsedKey:
    """A zone seat key taken apart: the manager, its zone and (a leader's) term."""
    mid = validate_id(parts[1], f"manager id in key {key!r}")
    zone = validate_id(parts[3], f"zone in key {key!r}")
    if kind == "zone_standby":
        return ParsedKey(kind=kind, ident=mid, parent=zone)
    term = parts[5]
    if not term.isdigit() or int(term) < 1 or len(term) > _MAX_TERM_DIGITS:
        raise ConfigError(f"key {key!r}: a leader's term is a positive integer, got {term!r}")
    return ParsedKey(kind=kind, ident=mid, parent=zone, term=int(term))
