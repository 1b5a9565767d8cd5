"""Zone ownership: each zone manager publishes the people it owns, exactly one manager per person at an instant,
the owner kept across the overlap band (hysteresis)."""

from __future__ import annotations

import numpy as np
import pytest

from common.area import Area, rectangle, signed_depth
from common.schema import Track, TrackSet
from resource_manager.serve.zones import NEIGHBOUR_STALE_S, ZoneOwnership, owns
from tests.unit.common.tracks import T0, published

BAND = 1.0
WEST = Area.of(rectangle(0.0, 0.0, 5.0, 10.0))
EAST = Area.of(rectangle(5.0, 0.0, 10.0, 10.0))


def _track(tid: str, x: float, y: float = 5.0, vx: float = 0.0, t_ns: int = T0, mid: str = "m") -> Track:
    return published(tid, x, y, vx, t_ns, mid)


def _set(mid: str, tracks: list[Track], t_ns: int = T0) -> TrackSet:
    return TrackSet(manager_id=mid, seq=1, stamp_ns=t_ns, tracks=tracks)


def test_signed_depth_is_positive_inside_and_negative_outside() -> None:
    d = signed_depth(WEST, np.array([[4.0, 5.0], [5.5, 5.0], [2.5, 5.0], [-1.0, 5.0]]))
    np.testing.assert_allclose(d, [1.0, -0.5, 2.5, -1.0])
    assert signed_depth(WEST, np.zeros((0, 2))).shape == (0,)


@pytest.mark.parametrize(
    ("depth", "had", "claimed", "want"),
    [
        (1.5, False, True, True),  # deep inside: owned, whoever else claims
        (-1.5, True, False, False),  # beyond the band outside: released
        (0.3, False, False, True),  # inside, in the band, nobody publishes it: taken
        (-0.3, False, False, False),  # outside, in the band, not held: the neighbour's
        (-0.7, True, False, True),  # held, still within the band beyond the border: kept
        (0.3, False, True, False),  # inside but the neighbour holds it: it keeps it until past the band
    ],
)
def test_the_rule(depth: float, had: bool, claimed: bool, want: bool) -> None:
    assert owns(depth, BAND, had=had, claimed=claimed) is want


def test_both_holding_the_midpoint_settles_it() -> None:
    assert owns(0.1, BAND, had=True, claimed=True, shared_depth=0.02)
    assert not owns(-0.1, BAND, had=True, claimed=True, shared_depth=-0.02)


def _walk(speed_mps: float, noise_m: float, seed: int) -> tuple[list[bool], list[bool]]:
    """A person walking west to east across x = 5 at 10 Hz, each manager with its own noisy estimate: who
    publishes at each instant."""
    rng = np.random.default_rng(seed)
    west, east = ZoneOwnership(WEST, BAND), ZoneOwnership(EAST, BAND)
    pub_w, pub_e = [], []
    for k in range(int(8.0 / speed_mps * 10)):
        t = T0 + k * 100_000_000
        x = 1.0 + speed_mps * k / 10
        mine_w = [_track("west-1", x + rng.normal(0, noise_m), vx=speed_mps, t_ns=t, mid="west")]
        mine_e = [_track("west-1", x + rng.normal(0, noise_m), vx=speed_mps, t_ns=t, mid="east")]
        got_w = west.select(mine_w, t)
        got_e = east.select(mine_e, t)
        # each hears the other's set of this instant before its next one
        west.heard(_set("east", got_e, t), t)
        east.heard(_set("west", got_w, t), t)
        pub_w.append(bool(got_w))
        pub_e.append(bool(got_e))
    return pub_w, pub_e


def test_a_walk_across_the_border_is_published_by_one_manager_at_each_instant() -> None:
    pub_w, pub_e = _walk(1.4, 0.0, 0)
    assert all(a != b for a, b in zip(pub_w, pub_e, strict=True))
    first_e = pub_e.index(True)
    assert all(pub_w[:first_e]) and not any(pub_w[first_e:])
    # the handover happens band_m inside the east zone: x >= 6
    assert 1.0 + 1.4 * first_e / 10 >= 5.0 + BAND - 1e-9


def test_noisy_estimates_rarely_publish_twice_or_not_at_all() -> None:
    both = none = total = 0
    for seed in range(50):
        pub_w, pub_e = _walk(1.4, 0.03, seed)
        both += sum(a and b for a, b in zip(pub_w, pub_e, strict=True))
        none += sum(not a and not b for a, b in zip(pub_w, pub_e, strict=True))
        total += len(pub_w)
    assert both / total < 0.01 and none / total < 0.01, (both, none, total)


def test_a_neighbours_stale_set_claims_nobody() -> None:
    east = ZoneOwnership(EAST, BAND)
    east.heard(_set("west", [_track("west-1", 5.3, mid="west")]), T0)
    assert not east.select([_track("east-1", 5.3)], T0 + 1)  # in the band, the west publishes it
    later = T0 + int((NEIGHBOUR_STALE_S + 0.1) * 1e9)
    assert [t.track_id for t in east.select([_track("east-1", 5.3, t_ns=later)], later)] == ["east-1"]


def test_an_older_set_does_not_replace_a_newer_one() -> None:
    own = ZoneOwnership(EAST, BAND)
    own.heard(_set("west", [_track("west-1", 5.3, mid="west")], T0 + 5), T0)
    own.heard(_set("west", [], T0), T0)
    assert [t.track_id for t in own.theirs(T0)] == ["west-1"]


def test_nothing_to_publish_forgets_what_was_owned() -> None:
    own = ZoneOwnership(WEST, BAND)
    assert own.select([_track("west-1", 4.5)], T0)
    assert own.select([], T0 + 1) == [] and own.owned == set()
