"""Whole tracker runs on synthetic panoramic features: clutter, crossings, a person standing still, a view that
drops out, births at 2 and 30 fps."""

from __future__ import annotations

import dataclasses
import math
from collections import Counter

import msgspec
import numpy as np
import pytest

from common.angles import wrap_angle
from common.area import AreaSpec, rectangle
from common.schema import Blob, Features
from resource_manager.config import ManagerConfig
from resource_manager.track.model import TrackModel
from resource_manager.track.tracker import Tracker
from tests.unit.resource_manager.scenario import T0_NS as T0
from tests.unit.resource_manager.scenario import make_config, run_scenario
from tests.unit.resource_manager.synth import Cam, Person, ViewSpec, stack_views, view

SQUARE = [Cam("p1", 0.5, 0.5), Cam("p2", 7.5, 0.5), Cam("p3", 7.5, 5.5), Cam("p4", 0.5, 5.5)]


def _id_of_each_person(run_gt: list[dict[int, tuple[float, float]]], run_hyp: list[dict[str, tuple[float, float]]]):
    """person -> Counter of the track ids nearest them (within 0.5 m), per tick."""
    ids: dict[int, Counter[str]] = {}
    for g, h in zip(run_gt, run_hyp, strict=True):
        for k, (x, y) in g.items():
            near = [(math.hypot(x - hx, y - hy), tid) for tid, (hx, hy) in h.items()]
            d, tid = min(near, default=(math.inf, ""))
            if d < 0.5:
                ids.setdefault(k, Counter())[tid] += 1
    return ids


def test_a_false_blob_in_one_view_makes_no_track() -> None:
    """One camera reports a false blob (a flag, a screen) in every frame where nobody is; the other three see
    nothing there: it never becomes a track."""

    def add_clutter(batch: list[Features], rng: np.random.Generator) -> list[Features]:
        fake = Blob(local_id=99, bearing_rad=wrap_angle(math.atan2(4.5, 1.5)), width_rad=0.1, top_elev_rad=0.12,
                    bottom_elev_rad=-0.3, bbox_u_px=0, bbox_v_px=10, bbox_w_px=10, bbox_h_px=30)  # fmt: skip
        return [
            Features(
                sensor_id=f.sensor_id,
                seq=f.seq,
                stamp_ns=f.stamp_ns,
                frame_index=f.frame_index,
                blobs=[*f.blobs, fake],
                sightings=f.sightings,
            )
            if f.sensor_id == "p1"
            else f
            for f in batch
        ]

    def people(t: float) -> list[Person]:
        return [Person(2.0 + 0.3 * t, 2.0, 1.75)]

    run = run_scenario(SQUARE, people, duration_s=12.0, seed=3, deliver=add_clutter)
    assert len(run.ids) == 1, run.ids
    assert run.mota["mota"] >= 0.95, run.mota


def test_two_people_crossing_keep_their_ids() -> None:
    """Two people walk towards each other along one line and pass 0.6 m apart: each keeps one id."""

    def people(t: float) -> list[Person]:
        return [Person(1.0 + 0.6 * t, 2.7, 1.85), Person(7.0 - 0.6 * t, 3.3, 1.6)]

    run = run_scenario(SQUARE, people, duration_s=10.0, seed=5)
    ids = _id_of_each_person(run.gt, run.hyp)
    for k in (0, 1):
        _, *rest = ids[k].most_common()
        assert sum(c for _, c in rest) <= 2, ids  # one id all along (a tick of jitter at most)
    assert ids[0].most_common(1)[0][0] != ids[1].most_common(1)[0][0]
    assert run.mota["mota"] >= 0.9, run.mota


def test_a_person_standing_still_for_a_minute_keeps_one_track() -> None:
    def people(t: float) -> list[Person]:
        return [Person(4.0, 3.0, 1.7), Person(2.0 + 0.05 * t, 1.5, 1.8)]

    run = run_scenario(SQUARE[:2], people, duration_s=62.0, seed=6)
    ids = _id_of_each_person(run.gt, run.hyp)
    assert len(ids[0]) == 1 and sum(ids[0].values()) >= 0.9 * len(run.gt), ids[0]  # from its birth to the end
    assert run.mota["mota"] >= 0.95


def test_a_view_that_drops_out_leaves_the_tracks_with_the_others() -> None:
    """From 5 s on camera p3 sends nothing at all (its node died): the people are still tracked by the other
    three, with the same ids."""

    def drop_p3(batch: list[Features], rng: np.random.Generator) -> list[Features]:
        return [f for f in batch if not (f.sensor_id == "p3" and f.stamp_ns > 5_000_000_000 + T0)]

    def people(t: float) -> list[Person]:
        return [Person(2.0 + 0.4 * math.sin(t / 3), 2.0, 1.7), Person(5.0, 4.0 - 0.3 * math.cos(t / 2), 1.8)]

    run = run_scenario(SQUARE, people, duration_s=14.0, seed=7, deliver=drop_p3)
    ids = _id_of_each_person(run.gt, run.hyp)
    assert all(len(c) == 1 for c in ids.values()), ids
    assert run.mota["mota"] >= 0.95 and run.mean_error_m < 0.1


@pytest.mark.parametrize("fps", [2.0, 30.0])
def test_a_new_person_is_confirmed_within_about_a_second_at_2_and_at_30_fps(fps: float) -> None:
    """Existence counts one view's frames within ``evidence_time_s`` once: confirmation takes about as long at
    2 fps as at 30 fps (not 15 times longer or shorter)."""
    config = make_config(rate_hz=max(2.0 * fps, 10.0), latency_ms=1000.0 / fps + 100.0)

    def people(t: float) -> list[Person]:
        return [Person(3.0, 2.0, 1.75)] if t >= 3.0 else []

    run = run_scenario(SQUARE, people, duration_s=8.0, fps=fps, rate_hz=max(2.0 * fps, 10.0),
                       latency_s=1.0 / fps + 0.1, seed=8, config=config, keep_results=True)  # fmt: skip
    first = next(r.trackset.stamp_ns for r in run.results if r.trackset.tracks)
    delay_s = (first - T0) / 1e9 - 3.0
    assert -0.3 <= delay_s <= 1.6, delay_s  # (a fusion instant a little before the first frame holds its blobs)


def test_a_track_one_view_alone_sees_is_held_unreported_once_vaguer_than_a_person() -> None:
    """From 4 s to 10 s only p1's node sends (p2's is down) while the person walks a circle: a bearing alone leaves
    the range open and the track drifts along p1's ray. The tracking is the same whatever ``publish_sigma_m``; with
    the default (a person's width) the TrackSets leave out the track while it is that vague, and what they hold back
    is what was off, while two views report everything."""

    def p2_down(batch: list[Features], rng: np.random.Generator) -> list[Features]:
        return [f for f in batch if not (f.sensor_id == "p2" and 4e9 + T0 < f.stamp_ns < 10e9 + T0)]

    def people(t: float) -> list[Person]:
        return [Person(4.0 + 1.5 * math.cos(0.5 * t), 3.0 + 1.5 * math.sin(0.5 * t), 1.75)]

    def run(sigma_m: float):
        config = make_config(tracker={"publish_sigma_m": sigma_m})
        return run_scenario(SQUARE[:2], people, duration_s=16.0, seed=9, deliver=p2_down, config=config)

    default, vague = run(0.5), run(100.0)
    t_s = [2.0 + k / 10.0 for k in range(len(default.gt))]  # the scored fusion instants (warm-up 2 s, 10 Hz)
    held: list[float] = []
    kept: list[float] = []
    for t, g, a, b in zip(t_s, default.gt, default.hyp, vague.hyp, strict=True):
        assert a.items() <= b.items(), (t, a, b)  # the rule only holds reports back
        if t < 4.0 or t > 11.0:
            assert a == b, (t, a, b)  # two views place the person: everything is reported
        (px, py) = g[0]
        held += [math.hypot(x - px, y - py) for tid, (x, y) in b.items() if tid not in a]
        kept += [math.hypot(x - px, y - py) for x, y in a.values() if 4.0 < t < 10.0]
    assert len(held) >= 5, held
    assert float(np.mean(held)) > float(np.mean(kept)) + 0.2, (held, kept)


# -- who is who: ids through occlusion, gaps and exits (the hand-made cases) ----------------------------

TRIANGLE = [Cam("p1", 3.0, 0.5), Cam("p2", 5.0, 0.5), Cam("p3", 4.0, 5.5)]
"""Two cameras on the south wall, one on the north: someone just south of a person hides them from both."""
ROOM = rectangle(0.0, 0.0, 8.0, 6.0)


def _with_area(area: AreaSpec, **tracker: object) -> ManagerConfig:
    return msgspec.structs.replace(make_config(tracker=dict(tracker) or None), area=area)


def _drop(people: set[int], t0_s: float, t1_s: float, sensors: set[str] | None = None):  # type: ignore[no-untyped-def]
    """A ``deliver`` hook: the blobs of ``people`` (their local ids) vanish from ``sensors`` (all: None) between
    ``t0_s`` and ``t1_s``."""

    def deliver(batch: list[Features], rng: np.random.Generator) -> list[Features]:
        out = []
        for f in batch:
            t = (f.stamp_ns - T0) / 1e9
            hidden = t0_s <= t < t1_s and (sensors is None or f.sensor_id in sensors)
            out.append(
                msgspec.structs.replace(f, blobs=[b for b in f.blobs if b.local_id not in people]) if hidden else f
            )
        return out

    return deliver


def _near(run, xy_at, t0_s: float, t1_s: float, radius_m: float = 0.5) -> Counter[str]:  # type: ignore[no-untyped-def]
    """Track ids published within ``radius_m`` of ``xy_at(t)`` between ``t0_s`` and ``t1_s`` (fusion instants)."""
    out: Counter[str] = Counter()
    for res in run.results:
        t = (res.trackset.stamp_ns - T0) / 1e9
        if t0_s <= t <= t1_s:
            x, y = xy_at(t)
            out.update(tr.track_id for tr in res.trackset.tracks if math.hypot(tr.x_m - x, tr.y_m - y) < radius_m)
    return out


def test_a_person_hidden_behind_another_in_two_of_three_cameras_for_3_s_keeps_the_id() -> None:
    """B stands at (4, 3.2); A walks up and stands just south of B for 3 s, hiding B from p1 and p2 (only p3, to the
    north, still sees B), then walks on: B keeps one id all along."""

    def a_at(t: float) -> tuple[float, float]:
        come, go = min(max((t - 2.0) / 2.0, 0.0), 1.0), min(max((t - 7.0) / 2.0, 0.0), 1.0)
        return (6.5 - 2.5 * come - 2.5 * go, 1.5 + 0.9 * come - 0.9 * go)

    def people(t: float) -> list[Person]:
        return [Person(4.0, 3.2, 1.7), Person(*a_at(t), 1.85)]

    hide = _drop({0}, 4.0, 7.0, {"p1", "p2"})
    run = run_scenario(TRIANGLE, people, duration_s=12.0, seed=11, deliver=hide, keep_results=True)
    ids = _near(run, lambda t: (4.0, 3.2), 2.5, 12.0, radius_m=0.3)
    assert len(ids) == 1, ids


def test_a_person_missed_by_every_camera_for_4_s_comes_back_with_the_old_id() -> None:
    """Nobody sees A for 4 s (a pillar, a detector's bad moment) while A walks on slowly: the track ends and, when
    A is seen again where they could have walked, A has the old id back."""

    def a_at(t: float) -> tuple[float, float]:
        return (2.0 + 0.2 * t, 3.0)

    def people(t: float) -> list[Person]:
        return [Person(*a_at(t), 1.75), Person(6.0, 1.5, 1.6)]

    run = run_scenario(SQUARE, people, duration_s=16.0, seed=12, deliver=_drop({0}, 5.0, 9.0), keep_results=True,
                       config=_with_area(ROOM))  # fmt: skip
    before, after = _near(run, a_at, 2.5, 5.0), _near(run, a_at, 10.5, 16.0)
    assert len(before) == 1 and set(after) == set(before), (before, after)


def _one_blob(t0_s: float, t1_s: float):  # type: ignore[no-untyped-def]
    """A ``deliver`` hook: between ``t0_s`` and ``t1_s`` every view shows people 0 and 1 as one blob spanning both
    (a detector's box around two people standing together)."""

    def union(a: Blob, b: Blob) -> Blob:
        b_at = a.bearing_rad + wrap_angle(b.bearing_rad - a.bearing_rad)
        lo = min(a.bearing_rad - a.width_rad / 2, b_at - b.width_rad / 2)
        hi = max(a.bearing_rad + a.width_rad / 2, b_at + b.width_rad / 2)
        u0, u1 = min(a.bbox_u_px, b.bbox_u_px), max(a.bbox_u_px + a.bbox_w_px, b.bbox_u_px + b.bbox_w_px)
        return msgspec.structs.replace(
            a, bearing_rad=wrap_angle((lo + hi) / 2), width_rad=hi - lo, bbox_u_px=u0, bbox_w_px=u1 - u0,
            top_elev_rad=max(a.top_elev_rad, b.top_elev_rad), bottom_elev_rad=min(a.bottom_elev_rad, b.bottom_elev_rad),
        )  # fmt: skip

    def deliver(batch: list[Features], rng: np.random.Generator) -> list[Features]:
        out = []
        for f in batch:
            by_id = {b.local_id: b for b in f.blobs}
            together = t0_s <= (f.stamp_ns - T0) / 1e9 < t1_s and {0, 1} <= set(by_id)
            rest = [b for b in f.blobs if b.local_id > 1]
            out.append(msgspec.structs.replace(f, blobs=[*rest, union(by_id[0], by_id[1])]) if together else f)
        return out

    return deliver


def test_two_people_every_camera_saw_as_one_blob_for_5_s_keep_their_ids_when_they_part() -> None:
    """B walks up to A and stands 0.3 m beside them; for 5 s every camera boxes the two as one (their tracks become
    one), then B walks back the way they came: each has their own id again (B's back: they are a head taller)."""

    def b_at(t: float) -> tuple[float, float]:
        come, go = min(max((t - 1.0) / 2.0, 0.0), 1.0), min(max((t - 8.0) / 2.0, 0.0), 1.0)
        return (6.5 - 2.2 * come + 2.2 * go, 3.0)

    def people(t: float) -> list[Person]:
        return [Person(4.0, 3.0, 1.6), Person(*b_at(t), 1.9)]

    run = run_scenario(SQUARE, people, duration_s=14.0, seed=14, deliver=_one_blob(3.0, 8.0), keep_results=True,
                       config=_with_area(ROOM))  # fmt: skip
    a_ids = _near(run, lambda t: (4.0, 3.0), 0.5, 3.0, radius_m=0.3)
    b_ids = _near(run, b_at, 0.5, 3.0, radius_m=0.3)
    a_after = _near(run, lambda t: (4.0, 3.0), 10.5, 14.0, radius_m=0.3)
    b_after = _near(run, b_at, 10.5, 14.0)
    assert [a_ids.most_common(1)[0][0], b_ids.most_common(1)[0][0]] == [next(iter(a_after)), next(iter(b_after))]
    assert len(a_after) == len(b_after) == 1, (a_ids, b_ids, a_after, b_after)


def test_someone_leaving_by_the_door_and_someone_entering_there_get_different_ids() -> None:
    """A walks out through the door on the wall y = 0 (an exit of the area) and is gone; 2 s later B comes in there:
    B is a new person, not A back."""
    door = AreaSpec(polygon=ROOM.polygon, exits=[[[3.0, 0.0], [5.0, 0.0]]])

    def a_at(t: float) -> tuple[float, float]:
        return (4.0, max(3.0 - 0.6 * t, -3.0))

    def b_at(t: float) -> tuple[float, float]:
        return (4.0, min(-3.0 + 0.6 * max(t - 7.0, 0.0), 3.0))

    def people(t: float) -> list[Person]:
        return [Person(*a_at(t), 1.75), Person(*b_at(t), 1.75), Person(1.5, 4.5, 1.65)]

    # Outside the room (y < 0) the walls hide A and B from every camera.
    def walls(batch: list[Features], rng: np.random.Generator) -> list[Features]:
        t_of = {f.stamp_ns: (f.stamp_ns - T0) / 1e9 for f in batch}
        outside = lambda k, t: (a_at if k == 0 else b_at)(t)[1] < 0.0  # noqa: E731
        return [
            msgspec.structs.replace(
                f, blobs=[b for b in f.blobs if b.local_id > 1 or not outside(b.local_id, t_of[f.stamp_ns])]
            )
            for f in batch
        ]

    run = run_scenario(SQUARE, people, duration_s=16.0, seed=13, deliver=walls, keep_results=True,
                       config=_with_area(door))  # fmt: skip
    a_ids, b_ids = _near(run, a_at, 2.5, 4.5), _near(run, b_at, 13.0, 16.0)
    assert a_ids and b_ids and not set(a_ids) & set(b_ids), (a_ids, b_ids)


def test_a_camera_that_drops_out_for_5_s_leaves_every_id_as_it_was() -> None:
    def people(t: float) -> list[Person]:
        return [Person(2.0 + 0.3 * math.sin(t / 3), 2.0, 1.7), Person(5.5, 4.0 - 0.3 * math.cos(t / 2), 1.8)]

    def drop_p2(batch: list[Features], rng: np.random.Generator) -> list[Features]:
        return [f for f in batch if not (f.sensor_id == "p2" and 5e9 + T0 <= f.stamp_ns < 10e9 + T0)]

    run = run_scenario(SQUARE, people, duration_s=15.0, seed=14, deliver=drop_p2)
    ids = _id_of_each_person(run.gt, run.hyp)
    assert all(len(c) == 1 for c in ids.values()), ids


def test_low_confidence_blobs_alone_start_nobody() -> None:
    """Every camera sees someone only with low confidence (a detector's weak boxes): no track starts; the same
    blobs, sure, start one."""

    def weak(batch: list[Features], rng: np.random.Generator) -> list[Features]:
        return [msgspec.structs.replace(f, blobs=[msgspec.structs.replace(b, confidence=0.3) for b in f.blobs])
                for f in batch]  # fmt: skip

    def people(t: float) -> list[Person]:
        return [Person(3.0 + 0.1 * t, 3.0, 1.75)]

    assert run_scenario(SQUARE, people, duration_s=8.0, seed=15, deliver=weak).ids == set()
    assert len(run_scenario(SQUARE, people, duration_s=8.0, seed=15).ids) == 1


def test_no_track_is_born_outside_the_area() -> None:
    """The cameras see two people; one walks outside the site's area (beyond its east wall): only the one inside is
    ever tracked."""

    def people(t: float) -> list[Person]:
        return [Person(2.0 + 0.1 * t, 3.0, 1.75), Person(7.0 + 0.05 * t, 2.0, 1.7)]

    run = run_scenario(SQUARE, people, duration_s=10.0, seed=16, config=_with_area(rectangle(0.0, 0.0, 6.0, 6.0)),
                       keep_results=True)  # fmt: skip
    assert run.ids and all(tr.x_m < 6.0 for res in run.results for tr in res.trackset.tracks)
    assert len(run.ids) == 1, run.ids


def _walkers_whose_detections_land_on_one(**tracker: float):  # type: ignore[no-untyped-def]
    """A and B walk side by side, 0.6 m apart; for 1.5 s every camera's box of B lands on A (a detector's moment of
    boxing the nearer person twice), pulling B's track onto A's spot; then B is seen where B is again. Returns the
    ids near B before and after, and B's path."""

    def b_at(t: float) -> tuple[float, float]:
        return (1.5 + 0.5 * t, 3.3)

    def people(t: float) -> list[Person]:
        return [Person(1.5 + 0.5 * t, 2.7, 1.75), Person(*b_at(t), 1.7)]

    def onto_a(batch: list[Features], rng: np.random.Generator) -> list[Features]:
        out = []
        for f in batch:
            a = next((b for b in f.blobs if b.local_id == 0), None)
            if a is not None and 4.0 <= (f.stamp_ns - T0) / 1e9 < 5.5:
                blobs = [msgspec.structs.replace(a, local_id=1) if b.local_id == 1 else b for b in f.blobs]
                out.append(msgspec.structs.replace(f, blobs=blobs))
            else:
                out.append(f)
        return out

    run = run_scenario(SQUARE, people, duration_s=11.0, seed=17, deliver=onto_a, keep_results=True,
                       config=_with_area(ROOM, **tracker))  # fmt: skip
    return _near(run, b_at, 2.0, 4.0, radius_m=0.3), _near(run, b_at, 7.5, 11.0, radius_m=0.3)


def test_two_people_pulled_onto_one_spot_for_a_moment_keep_their_ids() -> None:
    """Two people the views have told apart stay two when their tracks stand on one spot for less than
    ``apart_time_s``: B keeps the id; were they merged within ``evidence_time_s`` (the rule for tracks never told
    apart), B would lose it. That is with gates of 5 sigmas; with the default wider ones B keeps the id under either
    rule."""
    before, after = _walkers_whose_detections_land_on_one(apart_time_s=2.0, gate_sigmas=5.0)
    assert len(before) == 1 and set(after) == set(before), (before, after)
    before, after = _walkers_whose_detections_land_on_one(apart_time_s=0.5, gate_sigmas=5.0)
    assert len(before) == 1 and set(after) != set(before), (before, after)
    before, after = _walkers_whose_detections_land_on_one(apart_time_s=0.5)
    assert len(before) == 1 and set(after) == set(before), (before, after)


def test_a_person_first_seen_at_the_door_is_predicted_to_walk_in_one_first_seen_mid_room_to_stand() -> None:
    """At 2 fps the first frame of a new person says nothing of how they walk. Someone who appears by the door
    came in through it: their track is predicted on into the room (a second person coming in behind them, where
    they stood a frame ago, is not taken for them). Someone who appears mid-room may walk any way."""
    from resource_manager.fusion import Batch, Fusion
    from tests.unit.resource_manager.synth import features_for, info_for

    fusion = Fusion(_with_area(AreaSpec(polygon=ROOM.polygon, exits=[[[3.0, 0.0], [5.0, 0.0]]])))
    rng = np.random.default_rng(4)
    infos = [info_for(c) for c in SQUARE]
    velocity = {}
    for tick in range(1, 4):
        t_ns = T0 + tick * 500_000_000
        people = [Person(1.0, 4.5, 1.65)] + ([Person(4.0, 0.3, 1.75), Person(6.0, 3.0, 1.7)] if tick == 3 else [])
        fusion.absorb(Batch(features=[features_for(c, people, SQUARE, t_ns, tick, rng) for c in SQUARE], infos=infos))
        fusion.step(t_ns)
    for tr in fusion.tracker.snapshots():
        velocity[round(float(tr.x[0]))] = tr.x[2:]
    assert set(velocity) == {1, 4, 6}, velocity  # the one there from the start, the one at the door, the one mid-room
    assert velocity[4][1] > 0.5 and abs(velocity[4][0]) < 0.1  # walking in, across the door
    assert np.hypot(*velocity[6]) < 0.1 and np.hypot(*velocity[1]) < 0.1


def test_of_one_person_followed_twice_the_track_shown_now_stays_not_an_older_one_that_lost_them() -> None:
    """Two confirmed tracks on one spot for a second, moving alike, never told apart: one person followed twice.
    The older one lost its person a while ago (1.5 m vague, less likely there than not: not reported); the younger
    has followed them since, and is what is published on them. The younger stays: ending it would hand the
    person's published id to a track that no longer knew where they were."""
    from resource_manager.stereo.match import MatchParams
    from resource_manager.stereo.matchers import get_matcher
    from resource_manager.track.births import BirthParams
    from resource_manager.track.state import TrackRecord

    births = BirthParams(MatchParams(), threshold=0.1, matcher=get_matcher("greedy"), max_pairs=16, width_rel_sigma=0.1)
    tracker = Tracker(TrackModel(), births, new_id=lambda: "unused")
    t_ns = 10**10
    x = np.array([[4.0, 3.0, 0.5, 0.0], [4.1, 3.0, 0.5, 0.0]])
    p = np.array([np.diag([1.5**2, 1.5**2, 0.3, 0.3]), np.diag([0.1**2, 0.1**2, 0.1, 0.1])])
    tracker.filter.add(
        x, p, height=np.full(2, 1.7), height_var=np.full(2, 0.01), logodds=np.array([-1.0, 9.0]), t_ns=t_ns
    )
    tracker.tracks = [
        TrackRecord(serial=1, born_ns=0, track_id="m-1", confirmed=True),
        TrackRecord(serial=2, born_ns=t_ns // 2, track_id="m-2", confirmed=True, detected=True),
    ]
    tracker.separation.since[(1, 2)] = t_ns - 10**9  # together for a second
    merged: list[tuple[int, int]] = []
    ended = tracker._prune(t_ns, lambda xy: np.ones(len(xy), dtype=bool), merged)
    assert ended == ["m-1"] and merged == [(1, 2)]
    assert [tr.track_id for tr in tracker.tracks] == ["m-2"]


def test_two_people_standing_closer_than_a_blob_width_apart_keep_two_ids() -> None:
    """A and B walk in side by side, close up to 0.35 m apart (less than a person's width: from no camera do their
    blobs' bearings differ by a blob's width), stand there 10 s and walk on together. Every view that sees both
    gives each its own blob, tick after tick, which one person followed twice would not: they stay two people
    with two ids (merged as one, the other would be born again and again)."""
    cams = [Cam(c.id, c.x, c.y, sigma_rad=math.radians(2.0)) for c in SQUARE]

    def side(t: float) -> tuple[float, float]:
        return 1.5 + 0.8 * min(t, 3.0) + 0.8 * max(t - 13.0, 0.0), 1.2 - 0.85 * min(max((t - 1.0) / 2.0, 0.0), 1.0)

    def a_at(t: float) -> tuple[float, float]:
        x, gap = side(t)
        return (x, 3.0 - gap / 2)

    def b_at(t: float) -> tuple[float, float]:
        x, gap = side(t)
        return (x, 3.0 + gap / 2)

    def people(t: float) -> list[Person]:
        return [Person(*a_at(t), 1.75), Person(*b_at(t), 1.65)]

    run = run_scenario(cams, people, duration_s=16.0, seed=1, keep_results=True, config=_with_area(ROOM))
    near_a, near_b = _near(run, a_at, 2.0, 16.0, radius_m=0.17), _near(run, b_at, 2.0, 16.0, radius_m=0.17)
    assert len(near_a | near_b) == 2 and near_a.most_common(1)[0][0] != near_b.most_common(1)[0][0], (near_a, near_b)
    assert run.mota["mota"] >= 0.95, run.mota


def test_a_coasting_track_takes_a_new_person_back_only_while_it_is_likelier_there_than_not() -> None:
    """A published track nobody detects now, 1 m vague, predicted at (4, 3); someone new is seen at (7, 3), within its
    reach. While the track is more likely there than not, the newcomer is its person found again; once less likely
    (its person left unseen, or it never had one), the newcomer starts a track of their own."""

    def newcomer_after(logodds: float) -> tuple[int, list[str]]:
        tracker = _one_published_track("m-old", logodds, np.diag([1.0, 1.0, 0.3, 0.3]), detected=False)
        t_ns = tracker._t_ns
        views = stack_views([view(f"p{k}", c, [(7.0, 3.0, 1.7, 3)]) for k, c in enumerate([(7.5, 0.5), (7.5, 5.5)])])
        out = tracker.step(views, t_ns + 500_000_000)
        return out.returned, [tr.track_id for tr in tracker.tracks]

    assert newcomer_after(1.0) == (1, ["m-old"])
    assert newcomer_after(-1.0) == (0, ["m-new"])  # and the old one, given up, has ended


def test_a_tentative_track_claims_a_blob_only_as_surely_as_it_is_someone() -> None:
    from resource_manager.track.observe import ViewScores
    from resource_manager.track.tracker import _assign_views

    # One view, one blob that fits a tentative track (row 1) a little better than a published one (row 0).
    scores = ViewScores(
        ln_lr=np.array([[3.0], [3.5]]), ln_miss=np.log1p(-np.array([0.9, 0.9])), p_detect=np.full(2, 0.9)
    )
    as_people = _assign_views(("cam",), [scores], np.array([1.0, 1.0]))
    assert [len(a) for a in as_people] == [0, 1]  # both people: the better fit takes it
    unsure = _assign_views(("cam",), [scores], np.array([1.0, 0.3]))
    assert [len(a) for a in unsure] == [1, 0]  # a tentative track likelier nobody than someone yields it
    # Alone, a poor fit is a published track's, but a tentative one likelier nobody leaves it unexplained.
    poor = ViewScores(ln_lr=np.array([[0.5]]), ln_miss=np.log1p(-np.array([0.9])), p_detect=np.full(1, 0.9))
    assert [len(a) for a in _assign_views(("cam",), [poor], np.array([1.0]))] == [1]
    assert [len(a) for a in _assign_views(("cam",), [poor], np.array([0.3]))] == [0]


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_views_are_assigned_each_on_its_own(seed: int) -> None:
    """Every view's gains worked out at once assign as each view's Hungarian step on its own gains would: views
    without blobs, blobs no track can take (-inf) and gains below zero included."""
    from scipy.optimize import linear_sum_assignment

    from resource_manager.track.observe import ViewScores
    from resource_manager.track.tracker import _assign_views

    rng = np.random.default_rng(seed)
    n = 6
    scores = []
    for m in (3, 0, 5, 1, 4):
        ln_lr = rng.normal(0.5, 2.0, (n, m))
        ln_lr[rng.random((n, m)) < 0.3] = -np.inf
        p = rng.uniform(0.0, 0.95, n)
        scores.append(ViewScores(ln_lr=ln_lr, ln_miss=np.log1p(-p), p_detect=p))
    claim = rng.uniform(0.2, 1.0, n)
    sids = tuple(f"c{k}" for k in range(len(scores)))
    want: list[list[tuple[str, int]]] = [[] for _ in range(n)]
    for sid, sc in zip(sids, scores, strict=True):
        gain = sc.gain_claimed(claim)
        r, c = linear_sum_assignment(np.where(np.isfinite(gain) & (gain > 0), gain, 0.0), maximize=True)
        for i, j in zip(r.tolist(), c.tolist(), strict=True):
            if np.isfinite(gain[i, j]) and gain[i, j] > 0:
                want[i].append((sid, j))
    got = _assign_views(sids, scores, claim)
    assert [[(a.sensor_id, a.blob) for a in row] for row in got] == want
    assert any(want)


def _one_track_after(detectors: tuple[str, ...], seen_by: tuple[int, ...]) -> float | None:
    """A published track at (4, 3) with log-odds 4; one tick at which only the views ``seen_by`` (of four around the
    room, with detectors ``detectors``) have its blob: its log-odds after (None: it ended)."""
    from tests.unit.resource_manager.synth import stack_views, view

    tracker = _one_published_track("m-1", 4.0, np.diag([0.01, 0.01, 0.01, 0.01]), detected=True)
    t_ns = tracker._t_ns
    corners = [(0.0, 0.0), (8.0, 0.0), (8.0, 6.0), (0.0, 6.0)]
    specs = [
        dataclasses.replace(view(f"p{k}", c, [(4.0, 3.0, 1.7, 1)] if k in seen_by else []), shared_detector=d)
        for k, (c, d) in enumerate(zip(corners, detectors, strict=True))
    ]
    tracker.step(stack_views(specs), t_ns + 500_000_000)
    return float(tracker.filter.logodds[0]) if tracker.tracks else None


def test_the_views_of_one_multi_view_detector_miss_a_person_once_not_once_each() -> None:
    """Four views miss a published person at once. Each camera's own detector: four misses, and the track ends. One
    multi-view detector drawn into the four views: one miss (its recall is ``p_detect`` before it is learnt), and the
    track lives on; where one of its views has the person's blob, the detector found them, and the other three
    views' misses say nothing."""
    own, shared = ("", "", "", ""), ("mv", "mv", "mv", "mv")
    assert _one_track_after(own, ()) is None
    after = _one_track_after(shared, ())
    assert after == pytest.approx(4.0 + math.log1p(-TrackModel().p_detect), abs=1e-6)
    seen_once_own, seen_once_shared = _one_track_after(own, (0,)), _one_track_after(shared, (0,))
    assert seen_once_shared is not None and seen_once_shared >= 4.0 - 1e-9
    assert seen_once_own is None or seen_once_own < seen_once_shared - 3.0


def _one_published_track(track_id: str, logodds: float, cov: np.ndarray, *, detected: bool) -> Tracker:
    """A tracker whose one track, published as ``track_id``, stands at (4, 3) with ``logodds`` and state covariance
    ``cov`` (4, 4) at t = 10 s."""
    from resource_manager.stereo.match import MatchParams
    from resource_manager.stereo.matchers import get_matcher
    from resource_manager.track.births import BirthParams
    from resource_manager.track.state import TrackRecord

    births = BirthParams(MatchParams(), threshold=0.1, matcher=get_matcher("greedy"), max_pairs=16, width_rel_sigma=0.1)
    tracker = Tracker(TrackModel(), births, new_id=lambda: "m-new")
    t_ns = 10**10
    tracker.filter.add(np.array([[4.0, 3.0, 0.0, 0.0]]), cov[None], height=np.full(1, 1.7),
                       height_var=np.full(1, 0.0001), logodds=np.array([logodds]), t_ns=t_ns)  # fmt: skip
    tracker.tracks = [TrackRecord(serial=1, born_ns=0, track_id=track_id, confirmed=True, detected=detected)]
    tracker._serial, tracker._t_ns = 1, t_ns
    return tracker


def _nearest_only(sid: str, at: tuple[float, float], person: np.ndarray) -> ViewSpec:
    """A corner camera (2.6 m up) that sees one person, its box's foot giving their floor distance."""
    return view(sid, at, [(float(person[0]), float(person[1]), 1.7, None)], z=2.6, sigma_deg=0.3, feet_sigma_m=0.15)


@pytest.mark.parametrize("off_m", [0.1, 0.2, -0.2])
def test_two_cameras_at_the_ends_of_one_line_through_two_people_do_not_swap_them(off_m: float) -> None:
    """Two people 0.45 m apart on the line between two opposite corner cameras: each camera sees only the person
    nearer it. Their tracks coasted a moment (0.3 m vague), the first one's a little off the line. Against where
    the other camera puts each track, each camera would give its blob to the other camera's track (the second
    pass relies on the other views' first choices, which change too): the tracks would swap. They do not."""
    from resource_manager.stereo.match import MatchParams
    from resource_manager.stereo.matchers import get_matcher
    from resource_manager.track.births import BirthParams
    from resource_manager.track.state import TrackRecord

    near, far = (0.2, 0.2), (7.8, 5.8)
    along = np.array([7.6, 5.6]) / math.hypot(7.6, 5.6)
    across = np.array([-along[1], along[0]])
    a = np.array(near) + 3.6 * along
    b = a + 0.45 * along
    births = BirthParams(MatchParams(), threshold=0.1, matcher=get_matcher("greedy"), max_pairs=16, width_rel_sigma=0.1)
    tracker = Tracker(TrackModel(), births, new_id=lambda: "unused")
    t_ns = 10**10
    x = np.array([[*(a + off_m * across), 0.0, 0.0], [*b, 0.0, 0.0]])
    p = np.repeat(np.diag([0.3**2, 0.3**2, 0.3, 0.3])[None], 2, axis=0)
    tracker.filter.add(x, p, height=np.full(2, 1.7), height_var=np.full(2, 0.01), logodds=np.full(2, 4.0), t_ns=t_ns)
    tracker.tracks = [
        TrackRecord(serial=1, born_ns=0, track_id="m-a", confirmed=True),
        TrackRecord(serial=2, born_ns=0, track_id="m-b", confirmed=True),
    ]
    tracker.step(stack_views([_nearest_only("near", near, a), _nearest_only("far", far, b)]), t_ns)
    at = {s.track_id: s for s in tracker.snapshots()}
    assert at["m-a"].views == ("near",) and at["m-b"].views == ("far",), at
    assert np.hypot(*(at["m-a"].xy - a)) < 0.15 and np.hypot(*(at["m-b"].xy - b)) < 0.15, at
