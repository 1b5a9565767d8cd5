"""Track identity: coasting tracks keep a bounded gate, slow down, and do not take another person's fix."""

from __future__ import annotations

import math

import msgspec
import numpy as np
import pytest

from resource_manager.association import Associator
from resource_manager.config import ManagerConfig, ManagerSection, MatchSection, PlannerSection, TrackerSection
from resource_manager.fixcheck import owned_elsewhere
from resource_manager.group import HOLD_MIN_HITS, hidden_in_group
from resource_manager.localize import Measurement
from resource_manager.looks import bhattacharyya, learn_look, mean_similarity
from resource_manager.match import ViewBlobs
from resource_manager.room import Room
from resource_manager.track import Tracker, TrackParams, TrackRecord, look_similarity
from resource_manager.views import AllBlobs
from tests.unit.resource_manager.scenario import T0_NS, run_scenario
from tests.unit.resource_manager.synth import Cam, Person, colour_hist


def _meas(x: float, y: float, sigma: float = 0.05) -> Measurement:
    return Measurement(np.array([x, y]), sigma**2 * np.eye(2), 1.75, "triangulation", ("a", "b"), sigma, ())


def _coasting(params: TrackParams, misses: int) -> tuple[Tracker, TrackRecord]:
    tracker = Tracker(params, lambda: "m-1")
    tr = tracker.spawn(_meas(0.0, 0.0), 0, {})
    for k in range(1, 6):  # walking +x at 1 m/s
        tracker.predict(k * 100_000_000)
        tracker.update(tr, _meas(0.1 * k, 0.0), {})
    for k in range(6, 6 + misses):
        tracker.predict(k * 100_000_000)
        tracker.miss(tr)
    return tracker, tr


def test_a_coasting_tracks_gate_stops_growing_at_max_gate() -> None:
    loose, tr_loose = _coasting(TrackParams(max_misses=50), misses=12)
    capped, tr_capped = _coasting(TrackParams(max_misses=50, max_gate_m=1.0), misses=12)
    far = _meas(float(tr_loose.x[0]) + 1.3, float(tr_loose.x[1]))
    near = _meas(float(tr_capped.x[0]) + 0.6, float(tr_capped.x[1]))
    assert math.isfinite(loose.gate_distance(tr_loose, far))
    assert math.isinf(capped.gate_distance(tr_capped, far))
    assert math.isfinite(capped.gate_distance(tr_capped, near))
    assert loose.position_gate_m(tr_loose) > 1.3
    assert capped.position_gate_m(tr_capped) <= 1.0


def test_a_coasting_track_slows_down_and_a_measured_one_does_not() -> None:
    _, kept = _coasting(TrackParams(max_misses=50), misses=10)
    _, damped = _coasting(TrackParams(max_misses=50, coast_damping_s=0.5), misses=10)
    _, active = _coasting(TrackParams(max_misses=50, coast_damping_s=0.5), misses=0)
    assert math.hypot(*kept.x[2:]) > 0.9
    assert math.hypot(*damped.x[2:]) < 0.2  # exp(-1 s / 0.5 s) of 1 m/s
    assert math.hypot(*active.x[2:]) > 0.9


def test_a_fix_outside_the_motion_gate_moves_the_track_but_not_its_velocity() -> None:
    # A fix taken outside the gate (the nodes' 2D tracks link it, match.link_gate_m) used to be a Kalman step
    # whose gain turned the 0.8 m jump into metres per second (paper1 replay: 2.2 m/s, the track walked off).
    tracker, tr = _coasting(TrackParams(max_misses=50), misses=0)
    walking = tr.x[2:].copy()
    tracker.predict(600_000_000)
    sideways = _meas(float(tr.x[0]), float(tr.x[1]) + 0.8)
    assert math.isinf(tracker.gate_distance(tr, sideways))
    tracker.update(tr, sideways, {})
    assert float(tr.x[1]) > 0.4  # the position follows the fix
    assert np.allclose(tr.x[2:], walking)  # the velocity is the prediction's
    assert tr.p[2, 2] == pytest.approx(tracker.params.init_speed_sigma_mps**2)  # ...and as uncertain as at birth
    inside = _meas(float(tr.x[0]) + 0.1 + 0.1, float(tr.x[1]))
    tracker.predict(700_000_000)
    assert math.isfinite(tracker.gate_distance(tr, inside))
    tracker.update(tr, inside, {})
    assert float(tr.x[2]) > float(walking[0])  # a fix inside the gate still steers the velocity


def _config(
    *,
    match: dict[str, object] | None = None,
    planner: dict[str, object] | None = None,
    shared_pairs: bool = False,
    **tracker: object,
) -> ManagerConfig:
    """Manager "m1" with these ``[match]``, ``[planner]`` and ``[tracker]`` keys, defaults elsewhere."""
    return ManagerConfig(
        manager=msgspec.convert({"id": "m1"}, ManagerSection),
        match=msgspec.convert({"shared_pairs": shared_pairs, **(match or {})}, MatchSection),
        planner=msgspec.convert(planner or {}, PlannerSection),
        tracker=msgspec.convert(tracker, TrackerSection),
    )


def test_a_fix_a_more_recently_measured_track_explains_better_is_not_a_coasting_tracks() -> None:
    tracker, active = _coasting(TrackParams(max_misses=50, max_gate_m=1.0), misses=0)
    _, lost = _coasting(TrackParams(max_misses=50, max_gate_m=1.0), misses=6)
    tracker.tracks.append(lost)
    lost.x[:2] = active.x[:2] + np.array([0.6, 0.0])
    tracks = tracker.tracks
    at_active = _meas(float(active.x[0]) + 0.05, float(active.x[1]))
    assert math.isfinite(tracker.gate_distance(lost, at_active))  # inside its gate...
    assert owned_elsewhere(tracker, lost, at_active, tracks)  # ...but the active one's
    assert not owned_elsewhere(tracker, active, at_active, tracks)
    at_lost = _meas(float(lost.x[0]) + 0.1, float(lost.x[1]))
    assert not owned_elsewhere(tracker, lost, at_lost, tracks)


CAMS = [Cam("c1", 0.0, 3.0), Cam("c2", 6.0, 0.0, yaw=math.pi / 2), Cam("c3", 6.0, 6.0, yaw=math.pi)]


def _crossing(t: float) -> list[Person]:
    """A and B walk diagonally across each other's path (crossing at (3.4, 3) at t = 3 s, 0.8 m/s)."""
    s = min(max(t - 1.0, 0.0), 5.0) * 0.8 / math.sqrt(1.0 + 0.25**2)
    return [
        Person(1.8 + s, 2.6 + 0.25 * s, 1.70, hist=colour_hist(0)),
        Person(1.8 + s, 3.4 - 0.25 * s, 1.85, hist=colour_hist(3)),
    ]


def _crossing_ids(shared_pairs: bool) -> tuple[list[set[str]], dict[str, float]]:
    cfg = _config(shared_pairs=shared_pairs, max_gate_m=1.0, coast_damping_s=0.5, max_misses=8)
    res = run_scenario(CAMS, _crossing, duration_s=8.0, config=cfg, keep_results=True, warmup_s=0.0)
    ids: list[set[str]] = [set(), set()]
    for r in res.results:
        t = (r.trackset.stamp_ns - T0_NS) / 1e9  # the world time of the fusion instant
        people = _crossing(t)
        if t < 1.0 or math.hypot(people[0].x - people[1].x, people[0].y - people[1].y) < 0.6:
            continue  # while they overlap, either track is near both
        for k, p in enumerate(people):
            ids[k].update(tr.track_id for tr in r.trackset.tracks if math.hypot(tr.x_m - p.x, tr.y_m - p.y) < 0.3)
    return ids, res.mota


def test_two_people_crossing_keep_their_ids_with_shared_blobs() -> None:
    """After the crossing c2 and c3 each see one blob for both (the nearer hides the other), c1 sees two: the
    hidden person is localised by pairing c1's own blob with the shared one, and both keep their ids."""
    ids, m = _crossing_ids(shared_pairs=True)
    assert len(ids[0]) == 1 and len(ids[1]) == 1 and ids[0] != ids[1], ids
    assert m["idsw"] == 0 and m["mota"] > 0.9, m
    lost, m_own = _crossing_ids(shared_pairs=False)  # own blobs only: one view left, that person is lost
    assert m_own["fn"] > 5 * m["fn"] + 20, (m_own, lost)


def _lose(tracker: Tracker, tr: TrackRecord, start: int, ticks: int) -> tuple[int, list[str]]:
    ended: list[str] = []
    for k in range(start, start + ticks):
        tracker.predict(k * 100_000_000)
        tracker.miss(tr)
        ended += [e.track_id for e in tracker.prune()]
    return start + ticks, ended


def _confirm(tracker: Tracker, x: float, y: float, start: int, colour: int | None = None) -> tuple[TrackRecord, int]:
    """A new track confirmed at (x, y) over three ticks; with ``colour``, the shirt its blobs showed while tentative."""
    new = tracker.spawn(_meas(x, y), start * 100_000_000, {})
    new.height_m = 1.75
    if colour is not None:
        new.looks = _look(colour)
    for k in range(start + 1, start + 3):
        tracker.predict(k * 100_000_000)
        tracker.update(new, _meas(x, y), {})
    return new, start + 3


def _relinking() -> tuple[Tracker, TrackRecord]:
    """A tracker that holds lost ids 2 s (relink_m 1 m), new ids m-2, m-3, ..., and its confirmed track m-1."""
    tracker, tr = _coasting(TrackParams(max_misses=3, relink_s=2.0, relink_m=1.0), misses=0)
    n = iter(range(2, 100))
    tracker.new_id = lambda: f"m-{next(n)}"
    tr.height_m = 1.75
    return tracker, tr


def test_a_lost_track_lends_its_id_to_a_new_track_where_it_was_lost() -> None:
    tracker, tr = _relinking()
    assert tr.track_id == "m-1"
    k, ended = _lose(tracker, tr, 6, 5)
    assert ended == [] and tr not in tracker.tracks and tracker.lost == [tr]  # held, not published, not ended
    again, k = _confirm(tracker, float(tr.x[0]) + 0.4, float(tr.x[1]), k)
    assert again.track_id == "m-1" and tracker.lost == []
    k, _ = _lose(tracker, again, k, 5)
    elsewhere, k = _confirm(tracker, float(again.x[0]) + 3.0, float(again.x[1]), k)  # someone else
    assert elsewhere.track_id == "m-2"
    _, ended = _lose(tracker, elsewhere, k, 25)  # 2.5 s: the first one's hold expires, then this one's
    assert ended == ["m-1", "m-2"] and tracker.lost == [] and tracker.tracks == []


def _view(bearings_deg: list[float], hists: list[list[float]], local_ids: list[int]) -> ViewBlobs:
    h = np.array(hists)
    n = len(bearings_deg)
    return ViewBlobs(
        sensor_id="c1",
        origin_xy=np.array([0.0, 0.0]),
        z_m=1.1,
        sigma_rad=math.radians(0.2),
        bearing_rad=np.radians(bearings_deg),
        width_rad=np.full(n, 0.1),
        top_elev_rad=np.full(n, 0.1),
        hist=h,
        local_id=np.array(local_ids, dtype=np.int64),
        hist_sqrt=np.sqrt(h),
    )


def test_people_who_meet_keep_their_blobs_by_colour() -> None:
    """Two tracks 3 m from a camera, 1.5 deg apart; this tick each blob sits slightly nearer the other track
    (and the node's ids swapped too). By position they swap; by the colour each track has shown this camera
    they keep their own."""
    red, blue = colour_hist(0), colour_hist(3)
    tracker = Tracker(TrackParams(), lambda: "m")
    a = tracker.spawn(_meas(3.0 * math.cos(math.radians(10.0)), 3.0 * math.sin(math.radians(10.0))), 0, {"c1": 1})
    b = tracker.spawn(_meas(3.0 * math.cos(math.radians(11.5)), 3.0 * math.sin(math.radians(11.5))), 0, {"c1": 2})
    view = _view([11.0, 10.5], [red, blue], [2, 1])  # red (a's shirt) nearer b, blue nearer a
    plain = Associator(_config(), tracker)
    (sup_a, sup_b), _ = plain.support({"c1": view}, [a, b])
    assert (sup_a["c1"], sup_b["c1"]) == (1, 0)  # swapped by position and ids alone
    cfg = _config(match={"look_weight": 1.0})
    learn_look(a, {"c1": 0}, {"c1": _view([10.0], [red], [1])})
    learn_look(b, {"c1": 0}, {"c1": _view([11.5], [blue], [2])})
    (sup_a, sup_b), _ = Associator(cfg, tracker).support({"c1": view}, [a, b])
    assert (sup_a["c1"], sup_b["c1"]) == (0, 1)


def _look(k: int) -> dict[str, np.ndarray]:
    return {"c1": np.sqrt(np.array(colour_hist(k))), "c2": np.sqrt(np.array(colour_hist(k)))}


def test_a_lost_track_lends_its_id_only_to_a_track_with_its_shirt() -> None:
    tracker, tr = _relinking()
    tr.looks = _look(0)
    k, _ = _lose(tracker, tr, 6, 5)
    other, k = _confirm(tracker, float(tr.x[0]) + 0.4, float(tr.x[1]), k, colour=3)
    assert other.track_id == "m-2" and tracker.lost == [tr]  # another shirt where m-1 was lost: someone else
    same, k = _confirm(tracker, float(tr.x[0]) - 0.5, float(tr.x[1]), k, colour=0)
    assert same.track_id == "m-1" and tracker.lost == []


def _side_by_side(colour_b: int) -> tuple[Tracker, TrackRecord, TrackRecord]:
    """Two confirmed tracks 0.2 m apart on the same blobs of two cameras (one was pulled onto the other)."""
    tracker = Tracker(TrackParams(relink_s=2.0), lambda: "m")
    a = tracker.spawn(_meas(1.0, 1.0), 0, {"c1": 4, "c2": 7})
    b = tracker.spawn(_meas(1.2, 1.0), 100_000_000, {"c1": 4, "c2": 7})
    for tr, colour in ((a, 0), (b, colour_b)):
        tr.state, tr.track_id, tr.looks = "confirmed", f"m-{colour}", _look(colour)
    return tracker, a, b


def test_two_confirmed_tracks_side_by_side_are_kept_when_their_shirts_differ() -> None:
    tracker, a, b = _side_by_side(colour_b=3)
    assert tracker.prune() == [] and tracker.tracks == [a, b]  # two people passing close
    tracker, a, b = _side_by_side(colour_b=0)
    assert tracker.prune() == [] and tracker.tracks == [a] and tracker.lost == [b]  # one person: the younger
    # copy goes, held for its id (a new track confirmed there soon takes it back)


def test_a_lost_track_with_a_sure_look_match_lends_its_id_from_further() -> None:
    """A person lost in a group reappears 1.8 m on: beyond the plain reach (1 m + 0.5 m/s), within the reach of
    a sure colour match (2 m + 1 m/s)."""
    for colour, expected in ((0, "m-1"), (None, "m-2")):
        tracker, tr = _coasting(TrackParams(max_misses=3, relink_s=2.0, relink_m=1.0), misses=0)
        tracker.new_id = lambda: "m-2"
        tr.height_m, tr.looks = 1.75, _look(0)
        k, _ = _lose(tracker, tr, 6, 5)
        new, _ = _confirm(tracker, float(tr.x[0]) + 1.8, float(tr.x[1]), k, colour=colour)  # None: the plain reach
        assert new.track_id == expected


def test_a_fix_in_someone_elses_colours_is_not_the_tracks() -> None:
    """A red track: a fix from two blue blobs (two other people's rays, or a neighbour's blob after a merge) is
    refused with ``fix_look_min``; red blobs are its own; a tentative track has no look to judge by."""
    red, blue = colour_hist(0), colour_hist(3)
    tracker = Tracker(TrackParams(), lambda: "m")
    tr = tracker.spawn(_meas(2.0, 2.0), 0, {})
    tr.state, tr.looks = "confirmed", _look(0)
    views = {"c1": _view([10.0, 20.0], [red, blue], [1, 2]), "c2": _view([30.0, 40.0], [red, blue], [1, 2])}
    cfg = _config(match={"look_weight": 1.0, "fix_look_min": 0.85})
    judge = Associator(cfg, tracker)
    assert judge._unlike(tr, (("c1", 1), ("c2", 1)), views)
    assert not judge._unlike(tr, (("c1", 0), ("c2", 0)), views)
    assert judge._unlike(tr, (("c1", 0), ("c2", 1)), views)  # half a red fix: the mean is below the floor
    off = Associator(_config(), tracker)
    assert not off._unlike(tr, (("c1", 1), ("c2", 1)), views)
    tr.state = "tentative"
    assert not judge._unlike(tr, (("c1", 1), ("c2", 1)), views)


def _cam_view(sid: str, origin: tuple[float, float], blobs: list[tuple[float, float, int]]) -> ViewBlobs:
    """A view at ``origin`` whose blobs are (world x, world y of the head, angular width deg, local id) seen there."""
    ox, oy = origin
    return ViewBlobs(
        sensor_id=sid,
        origin_xy=np.array(origin),
        z_m=1.1,
        sigma_rad=math.radians(0.2),
        bearing_rad=np.array([math.atan2(y - oy, x - ox) for x, y, _, _ in blobs]),
        width_rad=np.radians([w for _, _, w, _ in blobs]),
        top_elev_rad=np.full(len(blobs), 0.15),
        hist=None,
        local_id=np.array([k for _, _, _, k in blobs], dtype=np.int64),
    )


def _group(shared_width_deg: float) -> tuple[dict[str, ViewBlobs], TrackRecord, TrackRecord, Tracker]:
    """A at (3, 3) and B at (3.5, 3) walk side by side. c1 sees them apart; c2 and c3 see one blob for both,
    its head on B (the node found one head), ``shared_width_deg`` wide."""
    tracker = Tracker(TrackParams(), lambda: "m")
    a = tracker.spawn(_meas(3.0, 3.0), 0, {"c1": 1})
    b = tracker.spawn(_meas(3.5, 3.0), 0, {"c1": 2, "c2": 5, "c3": 7})
    for tr in (a, b):
        tr.state, tr.track_id = "confirmed", f"m-{tr.serial}"
    views = {
        "c1": _cam_view("c1", (0.0, 0.0), [(3.0, 3.0, 8.0, 1), (3.5, 3.0, 7.0, 2)]),
        "c2": _cam_view("c2", (6.0, 0.0), [(3.5, 3.0, shared_width_deg, 5)]),
        "c3": _cam_view("c3", (6.0, 6.0), [(3.5, 3.0, shared_width_deg, 7)]),
    }
    return views, a, b, tracker


def _group_config(coast_s: float) -> ManagerConfig:
    return _config(match={"group_coast_s": coast_s})


def test_a_wide_blob_explains_two_people_and_the_hidden_one_keeps_its_fix() -> None:
    """B takes the merged blob in c2 and c3; A, left with its own blob in c1 only, shares it. Its own ray and
    the merged blob's extent fix it where it is (no stereo pair would); its lateral error is corrected."""
    views, a, b, tracker = _group(shared_width_deg=17.0)  # 1.2 m at 4 m: two people
    assoc = Associator(_group_config(3.0), tracker)
    (own_a, own_b), (shared_a, _) = assoc.support(views, [a, b])
    assert own_a == {"c1": 0} and set(shared_a) == {"c2", "c3"}
    assert set(own_b) == {"c1", "c2", "c3"}
    a.x[:2] = [3.15, 2.85]  # predicted 0.21 m off, across c1's ray
    fix = assoc._group_measure(a, own_a, shared_a, views, 1_000_000_000)
    assert fix is not None and fix.method == "least_squares"
    assert math.hypot(fix.xy[0] - 3.0, fix.xy[1] - 3.0) < 0.08, fix.xy  # back on c1's ray, near the truth
    assert fix.blobs == (("c1", 0),)  # its links: its own blob only, the merged one stays B's
    assert Associator(_group_config(0.0), tracker)._group_measure(a, own_a, shared_a, views, 1_000_000_000) is None
    late = assoc._group_measure(a, own_a, shared_a, views, 4_000_000_000)  # 4 s after its last stereo fix
    assert late is None


def test_a_one_person_blob_is_not_a_group_to_hide_in() -> None:
    """The same views with c2's and c3's blob one person wide: it is B's alone, A is not fixed on it."""
    views, a, b, tracker = _group(shared_width_deg=7.0)  # 0.5 m at 4 m
    assoc = Associator(_group_config(3.0), tracker)
    (own_a, _), (shared_a, _) = assoc.support(views, [a, b])
    assert own_a == {"c1": 0} and shared_a
    assert assoc._group_measure(a, own_a, shared_a, views, 1_000_000_000) is None


def test_a_grouped_track_without_its_own_2d_track_is_not_fixed() -> None:
    """The own blob must continue the node's 2D track the track followed (same local id)."""
    views, a, b, tracker = _group(shared_width_deg=17.0)
    a.links = {"c1": 9}
    assoc = Associator(_group_config(3.0), tracker)
    (own_a, _), (shared_a, _) = assoc.support(views, [a, b])
    assert assoc._group_measure(a, own_a, shared_a, views, 1_000_000_000) is None


def test_colour_similarity_is_one_bhattacharyya_in_every_shape() -> None:
    red, blue = np.sqrt(np.array(colour_hist(0))), np.sqrt(np.array(colour_hist(3)))
    bc = bhattacharyya(np.array([red, blue]), [red, None, blue, np.ones(3)])
    assert bc.shape == (2, 4)
    assert bc[0, 0] == pytest.approx(1.0) and bc[1, 2] == pytest.approx(1.0)
    assert bc[0, 2] == pytest.approx(float(red @ blue)) and bc[0, 2] < 0.5
    assert np.isnan(bc[:, 1]).all() and np.isnan(bc[:, 3]).all()  # no look, or another histogram size
    assert mean_similarity([(red, red), (red, blue), (blue, None)]) == pytest.approx((1.0 + float(red @ blue)) / 2)
    assert mean_similarity([(red, None)]) is None
    one, two = TrackRecord(1, np.zeros(4), np.eye(4), 0, 0), TrackRecord(2, np.zeros(4), np.eye(4), 0, 0)
    one.looks, two.looks = {"c1": red, "c2": red}, {"c2": blue, "c3": blue}
    assert look_similarity(one, two) == pytest.approx(float(red @ blue))  # over the one view both have


def test_a_well_followed_track_hidden_in_its_group_walks_with_it() -> None:
    """A has no view of its own at all this tick: c1 sees one blob for both too. All its views hold its
    predicted bearing and the blobs are two people wide, owned by B: it is held where it is (no miss, no velocity);
    a young track (the ghosts of the first seconds) or one whose views look elsewhere is not held."""
    views, a, b, tracker = _group(shared_width_deg=17.0)
    views["c1"] = _cam_view("c1", (0.0, 0.0), [(3.5, 3.0, 15.0, 2)])
    a.x[2:] = [0.8, 0.0]
    assoc = Associator(_group_config(3.0), tracker)
    (own_a, own_b), (shared_a, _) = assoc.support(views, [a, b])
    assert own_a == {} and set(shared_a) == {"c1", "c2", "c3"}
    owner = dict.fromkeys(own_b.items(), b)
    a.hits = HOLD_MIN_HITS - 1
    assert not assoc._hold_in_group(a, own_a, shared_a, views, 1_000_000_000, owner)
    a.hits, a.misses = HOLD_MIN_HITS, 2
    assert assoc._hold_in_group(a, own_a, shared_a, views, 1_000_000_000, owner)
    assert a.state == "coasting" and a.misses == 2
    assert np.allclose(a.x[2:], 0.0)  # held in place: a standing person does not walk off with a passer-by
    a.x[:2] = [2.0, 3.6]  # predicted out of the blobs: it is not in this group
    assert not hidden_in_group(a.x[:2], own_a, shared_a, views)
    narrow, *_ = _group(shared_width_deg=7.0)
    assert not hidden_in_group(np.array([3.0, 3.0]), {"c1": 0}, {"c2": 0, "c3": 0}, narrow)
    alone = dict.fromkeys(own_b.items(), a)  # the blobs are nobody else's: no group
    a.x[:2] = [3.0, 3.0]
    assert not assoc._hold_in_group(a, own_a, shared_a, views, 1_000_000_000, alone)


def test_nobody_is_fixed_or_born_outside_the_room() -> None:
    """With ``[planner] room`` 6 x 8 m and the 0.5 m margin: a pair of rays meeting at y = 9 m (near-colinear
    cameras put fixes far along the ray) is outside (``in_room``, which also gates every fix) and starts no track;
    at y = 7 m it does."""
    from tests.unit.resource_manager.test_rm_match import view

    def born(y: float) -> list[TrackRecord]:
        cfg = _config(planner={"room": [0.0, 0.0, 6.0, 8.0]})
        tracker = Tracker(TrackParams(), lambda: "m")
        assoc = Associator(cfg, tracker)
        views = {"c1": view("c1", (0.5, 0.5), [(3.0, y, 1.8, 1)]), "c2": view("c2", (5.5, 0.5), [(3.0, y, 1.8, 1)])}
        assoc.births.run(views, {sid: set() for sid in views}, {}, 0, lambda _m: True)
        assert assoc.in_room(np.array([3.0, y])) == (y <= 8.5)
        return tracker.tracks

    assert len(born(7.0)) == 1
    assert born(9.0) == []


def test_a_coasting_track_stops_at_the_wall() -> None:
    """A track predicted 0.3 m through the far wall (y = 8) by a velocity built from fixes along near-colinear
    rays comes back to the wall without its velocity into it; its velocity along the wall stays."""
    tr = TrackRecord(1, np.array([2.9, 8.3, 0.4, 1.5]), np.eye(4), 0, 0)
    room = Room(0.0, 0.0, 6.0, 8.0)
    room.stop_at_walls(tr)
    assert np.allclose(tr.x, [2.9, 8.0, 0.4, 0.0])
    inside = TrackRecord(2, np.array([2.9, 7.3, 0.4, 1.5]), np.eye(4), 0, 0)
    room.stop_at_walls(inside)
    assert np.allclose(inside.x, [2.9, 7.3, 0.4, 1.5])


def _measure_alone(
    assoc: Associator, tr: TrackRecord, sup: dict[str, int], views: dict[str, ViewBlobs]
) -> Measurement | None:
    """Step 2's fix of one track supported by ``sup``, the only track this tick, poses exact."""
    from resource_manager.pairmatch import PairMatches

    meas, _, _ = assoc._measure(
        tr,
        sup=sup,
        views=views,
        tracks=[tr],
        cache=PairMatches(views, [tr], assoc.params, assoc.matcher, assoc.threshold),
        pose_sigma={},
        ranked=assoc._rank(tr, sup, views, {}, set()),
        claimed=set(),
    )
    return meas


def test_three_cameras_on_a_confirmed_track_outvote_one_that_missed_it() -> None:
    """c1, c2 and c3 see the tracked person at (3, 3); c4, which should, has only someone else far to the side
    (a missed detection: with four cameras ``min_view_agreement`` 0.8 asks all four). The confirmed track takes
    its fix; a tentative one (which could be a ghost) does not."""
    from tests.unit.resource_manager.test_rm_match import view

    person = (3.0, 3.0, 1.8, 1)
    views = {
        "c1": view("c1", (0.0, 0.0), [person]),
        "c2": view("c2", (6.0, 0.0), [person]),
        "c3": view("c3", (6.5, 5.0), [person]),
        "c4": view("c4", (0.0, 6.5), [(1.0, 4.0, 1.7, 2)]),
    }

    def fix(state: str) -> Measurement | None:
        tracker = Tracker(TrackParams(), lambda: "m")
        tr = tracker.spawn(_meas(3.0, 3.0), 0, {"c1": 0, "c2": 0, "c3": 0})
        tr.state = state
        assoc = Associator(_config(), tracker)
        assoc._all = AllBlobs.of(views, 4.0)
        (sup,), _ = assoc.support(views, [tr])
        assert set(sup) == {"c1", "c2", "c3"}
        return _measure_alone(assoc, tr, sup, views)

    confirmed = fix("confirmed")
    assert confirmed is not None and math.hypot(confirmed.xy[0] - 3.0, confirmed.xy[1] - 3.0) < 0.05
    assert fix("tentative") is None


def test_a_well_followed_tracks_fix_is_the_one_nearest_its_prediction() -> None:
    """A at (3, 3), B at (3.4, 3.4) behind A as c1 sees them (one blob there). The support step gave A's track
    B's blob in c2 (the node's 2D ids swapped in a crossing); Eq. 7 pairs A's c1 blob with A's own c2 blob. A
    well-followed track takes that fix, on its prediction, over its own blobs' fix ~0.5 m off; a young track's
    prediction does not judge (it may sit between two people): it keeps its own blobs' fix."""
    from tests.unit.resource_manager.test_rm_match import view

    a, b = (3.0, 3.0, 1.8, 1), (3.4, 3.4, 1.7, 1)
    views = {"c1": view("c1", (0.0, 0.0), [a]), "c2": view("c2", (6.0, 0.0), [a, b])}

    def fix(hits: int) -> Measurement | None:
        tracker = Tracker(TrackParams(), lambda: "m")
        tr = tracker.spawn(_meas(3.0, 3.0, sigma=0.2), 0, {})
        tr.state, tr.hits = "confirmed", hits
        assoc = Associator(_config(), tracker)
        assoc._all = AllBlobs.of(views, 4.0)
        return _measure_alone(assoc, tr, {"c1": 0, "c2": 1}, views)  # the support gave it B's blob in c2

    followed = fix(HOLD_MIN_HITS)
    assert followed is not None and math.hypot(followed.xy[0] - 3.0, followed.xy[1] - 3.0) < 0.05
    young = fix(5)
    assert young is not None and math.hypot(young.xy[0] - 3.0, young.xy[1] - 3.0) > 0.2
