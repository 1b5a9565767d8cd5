"""Track life: where people can leave, returns of coasting tracks, one person followed twice, re-identification."""

from __future__ import annotations

import math

import numpy as np
import pytest

from common.area import Area, AreaSpec
from resource_manager.track.life import (
    Graveyard,
    Lost,
    NewTrack,
    Separation,
    at_exit,
    blobs_show_two,
    entry_velocity,
    existence_caps,
    left_area,
    match_returns,
    two_people_ln_odds,
)
from resource_manager.track.model import Scene, TrackModel, logit
from resource_manager.track.motion import MotionModel

MODEL = TrackModel()
ROOM = Area.of(AreaSpec(polygon=[[0.0, 0.0], [8.0, 0.0], [8.0, 6.0], [0.0, 6.0]], exits=[[[3.0, 0.0], [5.0, 0.0]]]))
SEES_ALL = lambda xy: np.ones(len(xy), dtype=bool)  # noqa: E731


def test_people_may_leave_at_a_door_outside_the_area_or_out_of_the_cameras_sight_only() -> None:
    xy = np.array([[4.0, 0.3], [1.0, 0.3], [4.0, 3.0], [4.0, -2.0]])
    sigma = np.full(4, 0.1)
    near = at_exit(xy, sigma, MODEL, Scene(area=ROOM), SEES_ALL)
    assert near.tolist() == [True, False, False, True]  # the door; a wall; the middle; outside
    blind_east = lambda p: p[:, 0] < 4.2  # noqa: E731 - no camera sees east of x = 4.2
    assert at_exit(xy[2:3], sigma[:1], MODEL, Scene(area=ROOM), blind_east).tolist() == [True]
    assert at_exit(xy, sigma, MODEL, Scene(), SEES_ALL).all()  # no area declared: anywhere
    caps = existence_caps(near, MODEL, Scene(area=ROOM))
    out, inside = logit(MODEL.p_max), logit(MODEL.p_max_inside)
    assert caps.tolist() == pytest.approx([out, inside, inside, out])


def test_a_person_first_seen_by_the_door_is_taken_to_walk_in_one_elsewhere_to_walk_anywhere() -> None:
    xy = np.array([[4.0, 0.2], [1.0, 0.2], [4.0, 3.0]])  # the door (on y = 0); a wall; the middle
    sigma = np.full(3, 0.1)
    sv = MODEL.speed_sigma_mps
    mean, cov = entry_velocity(xy, sigma, MODEL, Scene(area=ROOM))
    # Inward: of the walkers' law, those that crossed the door since the last look, as many as walk in that fast.
    assert mean[0] == pytest.approx([0.0, sv * math.sqrt(math.pi / 2.0)])
    assert cov[0] == pytest.approx(np.diag([sv**2, sv**2 * (2.0 - math.pi / 2.0)]))  # across the door only
    assert mean[1:] == pytest.approx(np.zeros((2, 2)))  # nobody comes in through a wall, or in the middle
    assert cov[1:] == pytest.approx(np.repeat(np.eye(2)[None] * sv**2, 2, axis=0))
    # First seen on the door's line, or a little beyond it: in all the same.
    on, _ = entry_velocity(np.array([[4.0, 0.0], [4.0, -0.05]]), np.full(2, 0.1), MODEL, Scene(area=ROOM))
    assert on == pytest.approx(np.repeat(mean[:1], 2, axis=0))
    corner = Area.of(AreaSpec(polygon=ROOM.polygon))  # no exits declared: the whole boundary is one
    mean, _ = entry_velocity(np.array([[7.8, 3.0], [4.0, 5.8]]), np.full(2, 0.1), MODEL, Scene(area=corner))
    assert mean[0, 0] < 0.0 and mean[1, 1] < 0.0  # in from the east wall, and from the north wall
    assert mean[0, 1] == pytest.approx(0.0) and mean[1, 0] == pytest.approx(0.0)
    closed = Area.of(AreaSpec(polygon=ROOM.polygon, exits=[]))
    for scene in (Scene(), Scene(area=closed)):  # no area, so no exits known; a room nobody enters
        assert not entry_velocity(xy, sigma, MODEL, scene)[0].any()


def test_a_track_surely_outside_the_area_has_left_one_at_its_edge_has_not() -> None:
    xy = np.array([[4.0, -1.5], [4.0, -0.1], [4.0, 3.0]])
    assert left_area(xy, np.full(3, 0.1), Scene(area=ROOM)).tolist() == [True, False, False]


def test_a_new_fix_where_a_coasting_track_is_predicted_is_that_track_one_far_off_is_not() -> None:
    cov = np.repeat(np.eye(2)[None] * 0.04, 2, axis=0)
    hyps = np.array([[1.1, 1.0], [5.0, 5.0]])
    tracks = np.array([[1.0, 1.0], [3.0, 3.0]])
    assert match_returns(hyps, cov, tracks, cov) == [(0, 0)]


def test_two_close_tracks_are_apart_while_the_views_make_them_likelier_two_and_forgotten_once_far() -> None:
    sep = Separation()
    xy = np.array([[0.0, 0.0], [0.3, 0.0]])
    sep.note([1, 2], xy, {}, 1_000_000_000)
    assert sep.since_apart_s(1, 2, 1_000_000_000) == math.inf and sep.together_s(2, 1, 1_500_000_000) == 0.5
    sep.note([1, 2], xy, {(0, 1): 2.0}, 2_000_000_000)
    assert sep.since_apart_s(2, 1, 2_500_000_000) == pytest.approx(0.5)
    sep.note([1, 2], xy, {(0, 1): -1.5}, 2_500_000_000)  # the odds gathered so far still say two
    assert sep.since_apart_s(2, 1, 2_500_000_000) == 0.0
    sep.note([1, 2], xy, {(0, 1): -1.5}, 3_000_000_000)  # now they say one: last seen apart at 2.5 s
    assert sep.since_apart_s(2, 1, 3_000_000_000) == pytest.approx(0.5)
    sep.note([1, 2], np.array([[0.0, 0.0], [3.0, 0.0]]), {}, 3_500_000_000)
    assert sep.since_apart_s(1, 2, 3_500_000_000) == math.inf and sep.together_s(1, 2, 3_500_000_000) == 0.0
    sep.note([1, 2], xy, {}, 4_000_000_000)  # close again: the odds start afresh
    assert sep.ln_odds == {(1, 2): 0.0}


def test_a_view_giving_two_close_tracks_two_blobs_says_two_people_one_blob_says_one() -> None:
    p = np.full(5, 0.9)
    got_a = np.array([True, True, False, False, True])
    got_b = np.array([True, False, True, False, True])
    hidden_b = np.array([0.9, 0.9, 0.9, 0.9, 0.0])  # the last view cannot see b: it says nothing of two or one
    ln = two_people_ln_odds(p, hidden_b, got_a, got_b)
    assert ln[0] > 2.0  # two blobs: two people (0.9 / 0.05)
    assert ln[1] < -1.0 and ln[2] == pytest.approx(ln[1])  # one blob, to either: one person
    assert ln[3] < 0.0  # none, where each of two people would likely show: one person (missed once)
    assert ln[4] == 0.0  # a blob to a track the view cannot see (found again): nothing either way
    # A view that should see neither says nothing either way.
    assert two_people_ln_odds(np.zeros(1), np.zeros(1), np.zeros(1, bool), np.zeros(1, bool)).tolist() == [0.0]
    # One hidden behind the other from a view: its one blob is what two people would give too.
    one = two_people_ln_odds(np.array([0.9]), np.array([0.05]), np.array([True]), np.array([False]))
    assert abs(float(one[0])) < 0.1


def test_two_blobs_show_two_people_only_each_on_its_own_side_and_neither_a_sliver_of_the_other() -> None:
    tracks = (0.00, 0.05)  # two close tracks' bearings from a view (rad)
    assert blobs_show_two(tracks, (0.00, 0.05), (0.08, 0.07))  # side by side, about as wide: two people
    assert blobs_show_two(tracks, (0.01, 0.04), (0.08, 0.08))  # overlapping boxes still count (one behind the other)
    assert not blobs_show_two(tracks, (0.05, 0.00), (0.08, 0.07))  # each on the other's side: a crossed assignment
    assert not blobs_show_two(tracks, (0.00, 0.06), (0.08, 0.03))  # a sliver beside a blob: maybe one cut in two


def test_close_tracks_another_manager_publishes_as_two_people_are_told_apart() -> None:
    sep = Separation()
    xy = np.array([[0.0, 0.0], [0.3, 0.0], [0.1, 0.2]])
    sep.note([1, 2, 3], xy, {}, 1_000_000_000)
    sep.told_apart({1, 2}, 2_000_000_000)
    assert sep.since_apart_s(2, 1, 2_500_000_000) == pytest.approx(0.5)
    assert sep.since_apart_s(1, 3, 2_500_000_000) == math.inf  # 3 follows none of the other's tracks
    sep.note([1, 2, 3], xy, {}, 2_100_000_000)  # no view shows them apart: what the other manager said holds
    assert sep.since_apart_s(1, 2, 2_500_000_000) == pytest.approx(0.5)


def _lost(xy: tuple[float, float], looks: dict[str, np.ndarray] | None = None) -> Lost:
    return Lost(
        track_id="m-1",
        ended_ns=2_000_000_000,
        seen_ns=1_000_000_000,
        x=np.array([xy[0], xy[1], 0.0, 0.0]),
        p=np.eye(4) * 0.01,
        height_m=1.8,
        height_var=0.001,
        looks=looks or {},
        look_s=dict.fromkeys(looks or {}, 5.0),
        serial=1,
    )


def _new(
    xy: tuple[float, float], height: float = 1.8, looks: dict[str, np.ndarray] | None = None, born_s: float = 3.0
) -> NewTrack:
    return NewTrack(int(born_s * 1e9), np.array(xy), height, 0.001, looks or {}, dict.fromkeys(looks or {}, 5.0))


def _match(new: list[NewTrack], lost: Lost, others: np.ndarray | None = None) -> list[tuple[int, Lost]]:
    g = Graveyard([lost])

    def colour(a, a_s, b, b_s):  # type: ignore[no-untyped-def]
        common = set(a) & set(b)
        return None if not common else sum(2.0 if np.allclose(a[s], b[s]) else -6.0 for s in common)

    return g.match(new, np.zeros((0, 2)) if others is None else others, model=MODEL, motion=MotionModel(0.8, 2.0),
                   colour_ln=colour, area_m2=48.0)  # fmt: skip


def test_a_lost_person_back_where_they_could_be_with_their_height_takes_their_id() -> None:
    (hit,) = _match([_new((2.3, 2.0))], _lost((2.0, 2.0)))
    assert hit[0] == 0 and hit[1].track_id == "m-1"
    assert _match([_new((2.3, 2.0), height=1.45)], _lost((2.0, 2.0))) == []  # not as tall
    assert _match([_new((7.5, 5.5))], _lost((2.0, 2.0))) == []  # too far for the gap


def test_without_colour_a_crowd_where_the_lost_one_could_be_decides_nothing_colour_does() -> None:
    someone = np.array([[2.2, 2.1]])
    assert _match([_new((2.3, 2.0))], _lost((2.0, 2.0)), others=someone) == []
    red = np.array([1.0, 0.0])
    assert _match([_new((2.3, 2.0), looks={"c": red})], _lost((2.0, 2.0), looks={"c": red}), others=someone)
    blue = np.array([0.0, 1.0])
    assert _match([_new((2.3, 2.0), looks={"c": blue})], _lost((2.0, 2.0), looks={"c": red})) == []


def test_without_colour_the_nearest_to_where_the_lost_one_should_be_is_them_within_the_turn_time() -> None:
    """Seen 2 s ago (the motion model's turn time), standing at (2, 2): a new track 0.1 m from there, with someone
    tracked 1 m away, is that person back; if the one tracked stands nearer, or after longer, it is nobody's."""
    someone = np.array([[3.0, 2.0]])
    (hit,) = _match([_new((2.1, 2.0))], _lost((2.0, 2.0)), others=someone)
    assert hit[1].track_id == "m-1"
    assert _match([_new((2.1, 2.0))], _lost((2.0, 2.0)), others=np.array([[2.0, 2.05]])) == []  # someone nearer
    assert _match([_new((2.1, 2.0), born_s=4.0)], _lost((2.0, 2.0)), others=someone) == []  # 3 s: anyone's
    assert _match([_new((2.1, 2.0), born_s=4.0)], _lost((2.0, 2.0)))  # 3 s, nobody about: still them
