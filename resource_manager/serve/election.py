"""Who of a zone's managers publishes: one leader, the others standbys, decided from zenoh liveliness alone.

Every manager of a zone (``[manager] zone``) holds one seat token under its own key
(:meth:`common.keys.Keys.zone_leader`, :meth:`~common.keys.Keys.zone_standby`) and watches the zone's seats with a
liveliness subscriber and, now and then, a liveliness ``get``. There is no message of its own: a seat is there
while its manager's session is (zenoh drops the tokens of a process killed, or of a host cut off, when its
transport goes), and this module turns the seats it sees into a role with two rules:

* **A standby claims** when it sees no leader, is the lowest id among the standbys it sees, and can lead (its
  sensors' frames reach it: a manager cut off from the site's router sees nobody either, and must not claim
  there). Its term is one above the highest term it has seen, so the newest claim outranks the older ones. A
  standby with lower ids before it claims too once the zone has been without a leader for ``CLAIM_WAIT_S`` per
  lower id: one that cannot lead (its sensors cut off) does not keep the zone leaderless. Should a lower one claim
  at the same moment after all, the second rule leaves one of them.
* **A leader yields** to any other leader that outranks it: the higher term, then the lower id. When a partition
  heals, both sides' leaders see each other again and exactly one keeps leading: the one that took over while
  the other was cut off (it has the sensors' frames of that time), or, between equals, the lower id.

A restarted manager (no term remembered) sees the leader's seat and stays a standby. The rules hold in any order
of arrival because each manager decides from the seats alone; :class:`Election` is that decision, pure, so the
node shell (resource_manager/node.py) only declares the token the role names.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Literal

__all__ = ["CLAIM_WAIT_S", "Election", "Role", "Seat"]

Role = Literal["leader", "standby"]


@dataclass(frozen=True, slots=True)
class Seat:
    """One manager's seat token as seen: its id, role and (a leader's) term."""

    manager_id: str
    role: Role
    term: int = 0


CLAIM_WAIT_S = 3.0
"""A standby waits this long per lower-id standby of its zone, after the leader has gone, before it claims in
their place: longer than a takeover (a fraction of a second) and than a re-read of the zone's seats (2 s)."""

MAX_HEARD = 256
"""Seats remembered (gone ones are forgotten first beyond it): a zone has a few managers, each a seat or two."""


@dataclass(slots=True)
class Election:
    """One manager's view of its zone's seats, and its role.

    What it hears comes numbered in arrival order: each seat change, and each whole view with the number of the
    last change heard before its read began. A whole view read across a change (begun before a leader was killed,
    answered after) is older than the change and does not undo it: each seat keeps what the newest news of it said.

    Args:
        manager_id: this manager (its own seats, echoed by zenoh, are not counted as another's).
    """

    manager_id: str
    role: Role = "standby"
    term: int = 0
    """This manager's term while it leads (0: never led)."""
    top_term: int = 0
    """The highest term seen (a new claim takes the next one)."""
    heard: dict[Seat, tuple[bool, int]] = field(default_factory=dict)
    """Every other manager's seat heard of: whether it is there, and the number of that news."""
    synced: bool = False
    """A first whole view has been read (no claim before: a leader may be there that has not been heard yet)."""
    leaderless_since_s: float | None = None
    """When (the caller's clock, s) this manager last saw its zone without a leader; None while there is one."""

    @property
    def leaders(self) -> dict[str, int]:
        """Other managers leading now: id -> their highest term."""
        out: dict[str, int] = {}
        for seat, (alive, _) in self.heard.items():
            if alive and seat.role == "leader":
                out[seat.manager_id] = max(seat.term, out.get(seat.manager_id, 0))
        return out

    @property
    def standbys(self) -> set[str]:
        """Other managers standing by now."""
        return {seat.manager_id for seat, (alive, _) in self.heard.items() if alive and seat.role == "standby"}

    def resync(self, seats: Iterable[Seat], number: int = 0) -> None:
        """A whole view (a liveliness ``get`` of the zone's seats), read after the news numbered ``number``: it
        replaces what that news and older said, not newer news."""
        there = {seat for seat in seats if seat.manager_id != self.manager_id}
        for seat in there:
            self._note(seat, alive=True, number=number)
        for seat, (alive, n) in list(self.heard.items()):
            if alive and seat not in there and n <= number:
                self.heard[seat] = (False, number)
        self.synced = True

    def saw(self, seat: Seat, alive: bool, number: int = 0) -> None:
        """A seat token came (``alive``) or went; ``number``: its place in the order of arrival."""
        if seat.manager_id != self.manager_id:
            self._note(seat, alive=alive, number=number)

    def _note(self, seat: Seat, *, alive: bool, number: int) -> None:
        if seat.role == "leader":
            self.top_term = max(self.top_term, seat.term)
        old = self.heard.get(seat)
        if old is None or old[1] <= number:
            self.heard[seat] = (alive, number)
        if len(self.heard) > MAX_HEARD:
            for gone in sorted((n, s.manager_id, s.term, s) for s, (a, n) in self.heard.items() if not a):
                del self.heard[gone[3]]
                if len(self.heard) <= MAX_HEARD:
                    break

    def leader(self) -> str | None:
        """The manager leading as this one sees it (itself included), or None."""
        ranked = sorted((-term, mid) for mid, term in self.leaders.items())
        if self.role == "leader":
            ranked = sorted([*ranked, (-self.term, self.manager_id)])
        return ranked[0][1] if ranked else None

    def decide(self, can_lead: bool, now_s: float = 0.0) -> bool:
        """Apply the two rules (see the module); True when this manager's role changed.

        ``can_lead``: the manager's sensors reach it now (a standby that cannot lead never claims). ``now_s``: a
        monotonic clock (s), for how long the zone has been without a leader."""
        if not self.synced:
            return False
        if self.role == "leader":
            if self.leader() != self.manager_id:
                self.role = "standby"
                return True
            return False
        if self.leaders:
            self.leaderless_since_s = None
            return False
        if self.leaderless_since_s is None:
            self.leaderless_since_s = now_s
        ahead = sum(1 for mid in self.standbys if mid < self.manager_id)
        if not can_lead or now_s - self.leaderless_since_s < ahead * CLAIM_WAIT_S:
            return False
        self.term = self.top_term + 1
        self.top_term = self.term
        self.role = "leader"
        return True
