"""The zone election: one leader from the seats alone, whatever order they are heard in."""

from __future__ import annotations

import itertools

import pytest

from resource_manager.serve.election import CLAIM_WAIT_S, Election, Seat


def _synced(mid: str, *seats: Seat) -> Election:
    e = Election(mid)
    e.resync(seats)
    return e


def test_nobody_claims_before_the_first_whole_view() -> None:
    e = Election("a")
    assert not e.decide(can_lead=True)
    assert e.role == "standby"


def test_alone_it_claims_the_first_term_once_its_sensors_reach_it() -> None:
    e = _synced("a")
    assert not e.decide(can_lead=False)
    assert e.decide(can_lead=True)
    assert (e.role, e.term, e.leader()) == ("leader", 1, "a")
    assert not e.decide(can_lead=True)


def test_a_manager_started_while_the_zone_has_a_leader_stands_by() -> None:
    e = _synced("a", Seat("b", "leader", 4))
    assert not e.decide(can_lead=True)
    assert (e.role, e.leader()) == ("standby", "b")


def test_when_the_leader_goes_the_lowest_standby_claims_the_next_term() -> None:
    b = _synced("b", Seat("a", "leader", 2), Seat("c", "standby"))
    c = _synced("c", Seat("a", "leader", 2), Seat("b", "standby"))
    for e in (b, c):
        e.saw(Seat("a", "leader", 2), alive=False)
    assert b.decide(can_lead=True) and (b.role, b.term) == ("leader", 3)
    assert not c.decide(can_lead=True) and c.role == "standby"


def test_a_standby_cut_off_from_its_sensors_never_claims() -> None:
    e = _synced("b", Seat("a", "leader", 1))
    e.saw(Seat("a", "leader", 1), alive=False)
    assert not e.decide(can_lead=False)
    assert e.role == "standby"


def test_a_standby_that_cannot_lead_does_not_keep_the_zone_leaderless() -> None:
    """The leader goes; a, the lowest standby, has lost its sensors. b claims after waiting one CLAIM_WAIT_S (a's
    turn), c after two; a back after b claimed stays a standby."""
    a = _synced("a", Seat("l", "leader", 1), Seat("b", "standby"), Seat("c", "standby"))
    b = _synced("b", Seat("l", "leader", 1), Seat("a", "standby"), Seat("c", "standby"))
    c = _synced("c", Seat("l", "leader", 1), Seat("a", "standby"), Seat("b", "standby"))
    for e in (a, b, c):
        assert not e.decide(can_lead=True, now_s=0.0)
        e.saw(Seat("l", "leader", 1), alive=False)
    assert not a.decide(can_lead=False, now_s=1.0)
    assert not b.decide(can_lead=True, now_s=1.0) and not c.decide(can_lead=True, now_s=1.0)
    assert not b.decide(can_lead=True, now_s=1.0 + 0.9 * CLAIM_WAIT_S)
    assert b.decide(can_lead=True, now_s=1.0 + CLAIM_WAIT_S) and (b.role, b.term) == ("leader", 2)
    for e in (a, c):
        e.saw(Seat("b", "leader", 2), alive=True)
    assert not c.decide(can_lead=True, now_s=1.0 + 2 * CLAIM_WAIT_S) and c.role == "standby"
    assert not a.decide(can_lead=True, now_s=1.0 + 2 * CLAIM_WAIT_S) and a.leader() == "b"


def test_two_standbys_claiming_at_once_leave_one_leader() -> None:
    """a claims; b, which has not heard a's leader seat yet, claims after its wait: both hold term 1. On hearing
    each other the higher id yields."""
    a = _synced("a", Seat("b", "standby"))
    b = _synced("b", Seat("a", "standby"))
    assert a.decide(can_lead=True, now_s=0.0)
    assert not b.decide(can_lead=True, now_s=0.0)
    assert b.decide(can_lead=True, now_s=CLAIM_WAIT_S) and a.term == b.term == 1
    a.saw(Seat("b", "leader", 1), alive=True)
    b.saw(Seat("a", "leader", 1), alive=True)
    assert not a.decide(can_lead=True, now_s=CLAIM_WAIT_S) and a.role == "leader"
    assert b.decide(can_lead=True, now_s=CLAIM_WAIT_S) and b.role == "standby" and b.leader() == "a"


def _lead(mid: str, term: int) -> Election:
    e = _synced(mid)
    e.top_term = term - 1
    assert e.decide(can_lead=True) and e.term == term
    return e


@pytest.mark.parametrize(("a_term", "b_term", "winner"), [(1, 2, "b"), (2, 1, "a"), (1, 1, "a"), (5, 5, "a")])
def test_after_a_partition_heals_exactly_one_leader_is_left(a_term: int, b_term: int, winner: str) -> None:
    """The newer term wins (it took over while the other was cut off); between equals, the lower id."""
    a, b = _lead("a", a_term), _lead("b", b_term)
    a.saw(Seat("b", "leader", b_term), alive=True)
    b.saw(Seat("a", "leader", a_term), alive=True)
    a.decide(can_lead=True)
    b.decide(can_lead=True)
    assert sorted(e.manager_id for e in (a, b) if e.role == "leader") == [winner]
    assert a.leader() == b.leader() == winner
    # The one that yielded stays a standby: the winner's seat is there.
    loser = a if winner == "b" else b
    assert not loser.decide(can_lead=True) and loser.role == "standby"


def test_a_whole_view_read_across_a_change_does_not_undo_it() -> None:
    """The view was asked before the leader's new seat was heard (number 7) and answered after: the seat stays."""
    e = _synced("b")
    e.saw(Seat("a", "leader", 1), alive=True, number=7)
    e.resync([], number=6)
    assert e.leaders == {"a": 1}
    e.resync([], number=7)  # read after that news: the leader is gone
    assert e.leaders == {}
    assert e.decide(can_lead=True) and e.term == 2


def test_its_own_seats_echoed_back_are_not_another_manager() -> None:
    e = _synced("a", Seat("a", "standby"), Seat("a", "leader", 3))
    assert e.leaders == {} and e.standbys == set()
    assert e.decide(can_lead=True)
    assert e.term == 1  # its own old term is not news: a restarted manager has no past


@pytest.mark.parametrize("order", list(itertools.permutations(range(3))))
def test_three_managers_hearing_the_seats_in_any_order_agree_on_one_leader(order: tuple[int, ...]) -> None:
    """Three managers start at once: each reads the others' standby seats, the lowest id claims, the others then
    hear its leader seat (in any order of the decisions)."""
    ids = ["m1", "m2", "m3"]
    es = {m: _synced(m, *(Seat(o, "standby") for o in ids if o != m)) for m in ids}
    for i in order:
        m = ids[i]
        if es[m].decide(can_lead=True):
            for o in ids:
                if o != m:
                    es[o].saw(Seat(m, "leader", es[m].term), alive=True)
    assert [m for m in ids if es[m].role == "leader"] == ["m1"]
    assert {es[m].leader() for m in ids} == {"m1"}
