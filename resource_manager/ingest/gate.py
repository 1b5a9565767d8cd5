"""The manager's gate: which senders it fuses, and the messages it refuses before they reach Fusion.

Three checks, in the order a message meets them:

1. *by key, before decoding*: a sensor id the manager was not told to fuse (its
   site's sensors, or ``[manager] sensors``) is refused; ``*`` accepts any;
2. *identity*: the payload must name the sender its key names
   (``sensor/{id}/features`` carries ``Features.sensor_id == id``); a message
   that speaks for another sender is refused, so a certificate that may only
   publish its own keys cannot file data under another sensor's id;
3. *clock*: Features stamped further than ``max_skew_ns`` behind the manager's
   own NTP-corrected clock (``skewed``), or more than ``max_lead_ns`` ahead of it (``ahead``) (nothing is
   captured in the future: only the hosts' NTP error), are refused and never
   buffered, so a frame from 2262 cannot become a sensor's "newest frame", one
   from 1970 cannot restart its buffer, and forged frames stamped just ahead
   cannot stand in for the real ones after a flood.

Every refusal is counted per sender id for ManagerStatus, with the sightings the
pose solver refused (reason ``sighting``: :mod:`resource_manager.poses.solver`). The counts are kept
for at most ``max_senders`` ids (a flood of fresh ids cannot grow memory), the
listed sensors' always; the rest are summed under :attr:`RefusalCounter.others`.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Final, Literal

from common.schema import Features, PtzState, Refusal, SensorInfo

__all__ = ["ANY_SENSOR", "REASONS", "RefusalCounter", "RefusalReason", "SenderGate", "sender_in_key"]

ANY_SENSOR: Final = "*"
"""The sensor list entry that accepts any sensor (``[manager] sensors = ["*"]``)."""

RefusalReason = Literal["unlisted", "wrong_id", "skewed", "ahead", "sighting"]
REASONS: Final[tuple[RefusalReason, ...]] = ("unlisted", "wrong_id", "skewed", "ahead", "sighting")
"""In the order of a counter's row. ``unlisted`` and ``wrong_id`` are what an impostor does; ``skewed`` (stamped
too far behind: a late frame, or a frame from 1970) and ``ahead`` (stamped in the future) are what a loaded host
or a clock off its NTP server does, as well as a forger; ``sighting``: sightings of another camera that the other
witnesses or that camera's settled pose contradict (a person hiding part of a band makes a few, a liar many)."""

_ID_RE: Final = re.compile(r"^[a-z0-9][a-z0-9-]{0,47}$")


def sender_in_key(key: str, head: str) -> str:
    """The chunk after ``head`` in ``key`` (``head`` = ``"{root}/sensor/"``), or "" if the key is not under it.

    A string split, not a full parse: it runs on every sample of a flood.
    """
    if not key.startswith(head):
        return ""
    rest = key[len(head) :]
    cut = rest.find("/")
    return rest if cut < 0 else rest[:cut]


@dataclass(slots=True)
class RefusalCounter:
    """Refused messages per sender id, bounded in the number of ids it remembers."""

    max_senders: int = 1024
    reserved: frozenset[str] = frozenset()
    """Ids always counted by name (the listed sensors): a flood of fresh ids cannot crowd them out."""
    counts: dict[str, list[int]] = field(default_factory=dict)
    """Sender id -> counts in the order of :data:`REASONS`."""
    others: int = 0
    """Refusals of senders beyond ``max_senders``, or whose key chunk is not a valid id."""
    total: int = 0

    def add(self, sender_id: str, reason: RefusalReason, n: int = 1) -> None:
        self.total += n
        row = self.counts.get(sender_id)
        if row is None:
            if sender_id not in self.reserved and (len(self.counts) >= self.max_senders or not _ID_RE.match(sender_id)):
                self.others += n
                return
            row = self.counts[sender_id] = [0] * len(REASONS)
        row[REASONS.index(reason)] += n

    def top(self, n: int) -> list[Refusal]:
        """The ``n`` senders with the most refusals, most first."""
        rows = sorted(self.counts.items(), key=lambda kv: (-sum(kv[1]), kv[0]))[:n]
        return [
            Refusal(sender_id=sid, unlisted=u, wrong_id=w, skewed=s, ahead=a, sighting=g)
            for sid, (u, w, s, a, g) in rows
        ]

    def senders(self) -> set[str]:
        return set(self.counts)


@dataclass(slots=True)
class SenderGate:
    """Decides, per message, whether the manager takes it.

    Args:
        sensors: the sensor ids to fuse; one entry ``"*"`` accepts any sensor.
        max_skew_ns: Features stamped further than this from the manager's clock are refused.
        max_lead_ns: ...and those stamped more than this ahead of it.
    """

    sensors: frozenset[str]
    max_skew_ns: int
    max_lead_ns: int
    refusals: RefusalCounter = field(default_factory=RefusalCounter)

    @classmethod
    def of(cls, sensors: Iterable[str], max_skew_ns: int, max_lead_ns: int | None = None) -> SenderGate:
        listed = frozenset(sensors)
        lead = max_skew_ns if max_lead_ns is None else min(max_lead_ns, max_skew_ns)
        return cls(listed, max_skew_ns, lead, RefusalCounter(reserved=listed))

    @property
    def any_sensor(self) -> bool:
        return ANY_SENSOR in self.sensors

    @property
    def expected(self) -> list[str]:
        """The listed sensors (empty when any is accepted)."""
        return [] if self.any_sensor else sorted(self.sensors)

    def allows(self, sensor_id: str) -> bool:
        """Whether messages keyed with this sensor id are taken at all (check 1)."""
        return self.any_sensor or sensor_id in self.sensors

    def refuse_unlisted(self, sensor_id: str, n: int = 1) -> None:
        self.refusals.add(sensor_id, "unlisted", n)

    def features(self, key_id: str, msg: Features, now_ns: int) -> bool:
        """Checks 2 and 3 for one decoded Features message under ``sensor/{key_id}/features``."""
        if msg.sensor_id != key_id:
            self.refusals.add(key_id, "wrong_id")
            return False
        lead_ns = msg.stamp_ns - now_ns
        if lead_ns > self.max_lead_ns:
            self.refusals.add(key_id, "ahead")
            return False
        if -lead_ns > self.max_skew_ns:
            self.refusals.add(key_id, "skewed")
            return False
        return True

    def same_sender(self, key_id: str, msg: SensorInfo | PtzState) -> bool:
        """Check 2 for SensorInfo and PtzState (their stamps are not capture times: no clock check)."""
        if msg.sensor_id != key_id:
            self.refusals.add(key_id, "wrong_id")
            return False
        return True

    def same_agent(self, key_agent: str, payload_agent: str) -> bool:
        """Check 2 for a PTZ request: the agent in its key must be the one in its payload."""
        if key_agent != payload_agent:
            self.refusals.add(key_agent, "wrong_id")
            return False
        return True
