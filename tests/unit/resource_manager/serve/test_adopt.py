"""A standby names its tracks after the leader's tracks of the same people."""

from __future__ import annotations

from common.schema import Track
from resource_manager.serve.adopt import GATE_M, adopt_ids, follows
from resource_manager.track.tracker import TrackSnapshot
from tests.unit.common.tracks import T0, published
from tests.unit.resource_manager.synth import snapshot


def _mine(serial: int, track_id: str, x: float, y: float, t_ns: int = T0) -> TrackSnapshot:
    return snapshot(serial, (x, y), track_id=track_id, method="paper", born_ns=T0, t_ns=t_ns)


def _theirs(track_id: str, x: float, y: float, vx: float = 0.0, t_ns: int = T0) -> Track:
    return published(track_id, x, y, vx, t_ns, mid="lead")


def _renames(mine: list[TrackSnapshot], theirs: list[Track]) -> dict[int, str]:
    return adopt_ids(mine, follows(mine, theirs))


def test_each_track_takes_the_id_of_the_leaders_nearest_one_to_one() -> None:
    mine = [_mine(1, "b-1", 0.0, 0.0), _mine(2, "b-2", 0.5, 0.0), _mine(3, "b-3", 5.0, 5.0)]
    theirs = [_theirs("a-7", 0.55, 0.05), _theirs("a-3", 0.05, 0.0), _theirs("a-9", 9.0, 9.0)]
    assert _renames(mine, theirs) == {1: "a-3", 2: "a-7"}  # b-3 has no leader track within the gate


def test_the_leaders_track_is_carried_to_the_standbys_instant() -> None:
    """The leader fused 0.2 s earlier; its person walks at 2 m/s: 0.4 m on, right onto the standby's track."""
    mine = [_mine(1, "b-1", 0.4, 0.0), _mine(2, "b-2", -0.3, 0.0)]
    theirs = [_theirs("a-1", 0.0, 0.0, vx=2.0, t_ns=T0 - 200_000_000)]
    assert _renames(mine, theirs) == {1: "a-1"}


def test_tentative_tracks_ids_already_held_and_far_tracks_are_left_alone() -> None:
    mine = [_mine(1, "", 0.0, 0.0), _mine(2, "a-4", 3.0, 0.0), _mine(3, "b-3", 3.1, 0.0), _mine(4, "b-4", 7.0, 0.0)]
    theirs = [_theirs("a-1", 0.0, 0.0), _theirs("a-4", 3.1, 0.0), _theirs("a-5", 7.0 + GATE_M + 0.01, 0.0)]
    # 1 is tentative (it follows a-1, to be confirmed under it); a-4 already named (2 keeps it whichever is
    # nearest); 4 is out of the gate.
    assert _renames(mine, theirs) == {}
    assert follows(mine, theirs) == {1: "a-1", 3: "a-4"}
    assert _renames([], theirs) == {} and _renames(mine, []) == {}


def test_two_tracks_may_swap_ids() -> None:
    """The leader's ids went the other way round (its own tracker swapped them): the standby's follow at once."""
    mine = [_mine(1, "a-1", 0.0, 0.0), _mine(2, "a-2", 2.0, 0.0)]
    theirs = [_theirs("a-2", 0.0, 0.0), _theirs("a-1", 2.0, 0.0)]
    assert _renames(mine, theirs) == {1: "a-2", 2: "a-1"}


def test_confirmed_tracks_are_matched_before_tentative_ones() -> None:
    """A tentative track nearer the leader's track than the confirmed one of that person does not take its id."""
    mine = [_mine(1, "b-1", 0.0, 0.3), _mine(2, "", 0.0, 0.05)]
    theirs = [_theirs("a-1", 0.0, 0.0)]
    assert follows(mine, theirs) == {1: "a-1"}
    assert _renames(mine, theirs) == {1: "a-1"}


def test_a_set_naming_one_id_twice_is_not_followed() -> None:
    mine = [_mine(1, "b-1", 0.0, 0.0), _mine(2, "b-2", 3.0, 0.0)]
    assert follows(mine, [_theirs("a-1", 0.0, 0.0), _theirs("a-1", 3.0, 0.0)]) == {}
