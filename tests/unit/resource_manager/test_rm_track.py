"""The tracker's model on small hand-made cases (resource_manager/track/): motion, visibility, the robust update,
births, existence, and whole runs with clutter, crossings, a person standing still and a view that drops out."""

from __future__ import annotations

import math
from collections import Counter

import numpy as np
import pytest

from common.schema import Blob, Features
from resource_manager.track.model import TrackModel
from resource_manager.track.motion import MotionModel, Observation, predict, update
from resource_manager.track.observe import TrackTable, visibility
from resource_manager.track.state import TrackRecord
from resource_manager.views.blobs import ViewBlobs
from tests.unit.resource_manager.scenario import T0_NS as T0
from tests.unit.resource_manager.scenario import make_config, run_scenario
from tests.unit.resource_manager.synth import Cam, Person, wrap

SQUARE = [Cam("p1", 0.5, 0.5), Cam("p2", 7.5, 0.5), Cam("p3", 7.5, 5.5), Cam("p4", 0.5, 5.5)]


# -- motion ----------------------------------------------------------------------------------------------------
def test_an_unseen_walker_is_predicted_to_stop_and_spread_like_a_random_walk() -> None:
    """The velocity decays over ``turn_time_s``: a walker unseen for long ends near where they were heading
    (τ·v further), and the position variance then grows about linearly in time, not with t³."""
    m = MotionModel(speed_sigma_mps=0.8, turn_time_s=2.0)
    x0, p0 = np.array([0.0, 0.0, 1.0, 0.0]), np.diag([0.01, 0.01, 0.01, 0.01])
    far, pf = predict(x0, p0, 30.0, m)
    assert far[0] == pytest.approx(2.0, abs=1e-6) and abs(far[2]) < 1e-6  # stopped τ·v = 2 m on
    _, p10 = predict(x0, p0, 10.0, m)
    _, p20 = predict(x0, p0, 20.0, m)
    growth = (pf[0, 0] - p20[0, 0]) / (p20[0, 0] - p10[0, 0])
    assert growth == pytest.approx(1.0, abs=0.1)  # 10 s more adds as much as the 10 s before: diffusion
    near, _ = predict(x0, p0, 0.1, m)
    assert near[0] == pytest.approx(0.1, abs=0.005)  # a frame later: still walking at 1 m/s
    same, same_p = predict(x0, p0, 0.0, m)
    assert same is x0 and same_p is p0


def _bearing(origin: tuple[float, float], xy: tuple[float, float], var: float = 1e-5) -> Observation:
    return Observation(origin, math.atan2(xy[1] - origin[1], xy[0] - origin[0]), var)


def test_bearings_from_three_cameras_pull_a_wide_prior_onto_the_person() -> None:
    person = (3.0, 4.0)
    x, p = np.array([4.5, 2.5, 0.0, 0.0]), np.diag([1.0, 1.0, 0.5, 0.5])
    obs = [_bearing(o, person) for o in ((0.0, 0.0), (8.0, 0.0), (0.0, 8.0))]
    xn, pn, w = update(x, p, obs)
    assert float(np.hypot(xn[0] - 3.0, xn[1] - 4.0)) < 0.01
    assert pn[0, 0] < 0.001 and pn[1, 1] < 0.001 and np.all(w == 1.0)


def test_one_wrong_view_is_down_weighted_by_the_others() -> None:
    """Three views agree on the person; a fourth gave another person's blob (3 m off): with the outlier
    component the estimate stays on the person and that view's weight falls; without, it is dragged off."""
    person = (3.0, 4.0)
    good = [_bearing(o, person) for o in ((0.0, 0.0), (8.0, 0.0), (0.0, 8.0))]
    wrong = _bearing((8.0, 8.0), (6.0, 4.0))
    x, p = np.array([3.2, 3.8, 0.0, 0.0]), np.diag([0.25, 0.25, 0.5, 0.5])
    robust, _, w = update(x, p, [*good, wrong], (0.05, 4.0))
    plain, _, _ = update(x, p, [*good, wrong])
    assert float(np.hypot(robust[0] - 3.0, robust[1] - 4.0)) < 0.02
    assert float(np.hypot(plain[0] - 3.0, plain[1] - 4.0)) > 0.1
    assert w[3] < 0.1 and np.all(w[:3] > 0.9)


# -- visibility ----------------------------------------------------------------------------------------------
def _panorama(origin: tuple[float, float], z_m: float) -> ViewBlobs:
    empty = np.zeros(0)
    return ViewBlobs("c", np.array(origin), z_m, 0.0035, empty, empty, empty, None, np.zeros(0, np.int64))


def _track(x: float, y: float, height: float = 1.7) -> TrackRecord:
    return TrackRecord(0, np.array([x, y, 0.0, 0.0]), np.eye(4) * 0.01, 0, 0, 0.0, height, 0.01)


def test_someone_behind_a_nearer_person_is_hidden_from_a_low_camera_not_from_a_high_one() -> None:
    """Angular silhouettes: at head height the far person's head is covered; from 6 m up it shows."""
    model = TrackModel()
    table = TrackTable.of([_track(3.0, 0.0), _track(6.0, 0.0), _track(3.0, 3.0)])
    low = visibility(_panorama((0.0, 0.0), 1.1), table, model)
    high = visibility(_panorama((0.0, 0.0), 6.0), table, model)
    assert low[0] == pytest.approx(model.p_detect) and low[2] == pytest.approx(model.p_detect)
    assert low[1] < 0.5  # wholly behind the nearer one
    assert high[1] > 0.7  # mostly visible above the nearer one's head
    far = TrackTable.of([_track(200.0, 0.0)])
    assert visibility(_panorama((0.0, 0.0), 1.1), far, model)[0] == 0.0  # out of range: no evidence either way


# -- whole runs on synthetic panoramic features ------------------------------------------------------------
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
        fake = Blob(local_id=99, bearing_rad=wrap(math.atan2(4.5, 1.5)), width_rad=0.1, top_elev_rad=0.12,
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
