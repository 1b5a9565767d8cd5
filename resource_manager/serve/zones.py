"""Which of a zone manager's tracks it publishes: the ones it owns.

A site cut into zones (``[[zones]]``) runs one manager per zone. Each fuses the cameras that see into its zone,
so both neighbours track a person near their shared border; only the owner publishes. Ownership is decided per
track, by each manager alone, from its own estimate of where the person is and from its neighbours' TrackSets
(which it hears on ``tracks``, as every agent does). ``depth`` is the signed distance of the person to the
manager's zone border (positive inside), ``band_m`` the half-width of the overlap band (``zone_band_m``):

* deeper inside than the band (``depth >= band_m``): owned;
* farther outside than the band (``depth <= -band_m``): not owned;
* in the band: a track owned at the last instant stays owned (hysteresis); one not owned becomes owned only if it
  is inside the zone (``depth >= 0``) and no neighbour publishes that person now (its newest TrackSet has no track
  within the gate of it). Two managers that both published the person (a rare instant: their estimates differ by
  centimetres) settle it by the midpoint of their two estimates: the zone that contains it keeps the person.

A person walking from zone A into B is published by A until it is ``band_m`` past A's border, and by B from the
instant it is ``band_m`` inside B's: along a shared border the same position, which both managers compare with the
same number, so the handover is a deterministic rule both apply at the same place, not a message they wait for (a
message would cost a tick of silence, the time A's last TrackSet takes to reach B). Their estimates differ by a few
centimetres, a person walks ~14 cm per tick at 10 Hz: rarely one instant is published by both or by none.

The id goes with the person: while B does not own a person it names its track after the neighbour's published one
(:func:`resource_manager.serve.adopt.adopt_ids`, the standby's machinery), so when B starts publishing it does so
under the id A published (the one minted by whoever first published the person: ids stay unique site-wide with no
allocator). Pure: positions in, decisions out; the node (resource_manager/node.py) keeps what was owned.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from common.area import Area, signed_depth
from common.schema import Track, TrackSet
from resource_manager.serve.adopt import GATE_M, carried, match_tracks

__all__ = ["ZoneOwnership", "owns"]

NEIGHBOUR_STALE_S = 1.0
"""A neighbour's newest TrackSet older than this (its manager gone, or cut off) claims nobody."""


def owns(depth: float, band_m: float, *, had: bool, claimed: bool, shared_depth: float | None = None) -> bool:
    """Whether a manager owns (publishes) a track this instant (the rule of the module's docstring).

    Args:
        depth: the track's signed depth in the manager's zone (m, positive inside).
        band_m: the overlap band's half-width.
        had: the manager owned it at its last instant.
        claimed: a neighbour publishes the same person now.
        shared_depth: when claimed, the signed depth of the midpoint of the two estimates (settles a person both
            published).
    """
    if depth >= band_m:
        return True
    if depth <= -band_m:
        return False
    if not claimed:
        return had or depth >= 0.0
    if had:
        return (depth if shared_depth is None else shared_depth) >= 0.0
    return False


@dataclass(slots=True)
class ZoneOwnership:
    """One zone manager's ownership of its tracks: its zone, the band, and what it owned at its last instant.

    Args:
        area: the zone's polygon.
        band_m: the overlap band's half-width (m).
        gate_m: how near a neighbour's track (carried to this instant) must be to be the same person.
    """

    area: Area
    band_m: float
    gate_m: float = GATE_M
    owned: set[str] = field(default_factory=set)
    """Ids published at the last instant."""
    neighbours: dict[str, tuple[int, TrackSet]] = field(default_factory=dict)
    """Each neighbour manager's newest TrackSet, with when (ns, this manager's clock) it arrived."""

    def heard(self, ts: TrackSet, now_ns: int) -> None:
        """A neighbour's TrackSet arrived (an older one than what is kept is ignored)."""
        old = self.neighbours.get(ts.manager_id)
        if old is None or ts.stamp_ns >= old[1].stamp_ns:
            self.neighbours[ts.manager_id] = (now_ns, ts)

    def theirs(self, now_ns: int) -> list[Track]:
        """The tracks the neighbours publish now (their newest TrackSets, the stale ones left out)."""
        stale = int(NEIGHBOUR_STALE_S * 1e9)
        for mid in [m for m, (at, _) in self.neighbours.items() if now_ns - at > stale]:
            del self.neighbours[mid]
        return [t for _, ts in self.neighbours.values() for t in ts.tracks]

    def select(self, tracks: Sequence[Track], now_ns: int) -> list[Track]:
        """The tracks this manager publishes of ``tracks`` (its set at one instant); remembers them as owned."""
        if not tracks:
            self.owned = set()
            return []
        theirs = self.theirs(now_ns)
        xy = np.array([[t.x_m, t.y_m] for t in tracks], dtype=np.float64)
        depth = signed_depth(self.area, xy)
        pairs = match_tracks(xy, np.array([t.stamp_ns for t in tracks]), theirs, self.gate_m)
        out = []
        for i, tr in enumerate(tracks):
            j = pairs.get(i)
            shared = None
            if j is not None:
                mid = (xy[i] + carried([theirs[j]], np.array([tr.stamp_ns]))[0, 0]) / 2.0
                shared = float(signed_depth(self.area, mid)[0])
            had = tr.track_id in self.owned
            if owns(float(depth[i]), self.band_m, had=had, claimed=j is not None, shared_depth=shared):
                out.append(tr)
        self.owned = {t.track_id for t in out}
        return out
