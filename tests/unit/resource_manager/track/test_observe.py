"""Visibility: who a camera can see past the people nearer to it; a bearing's variance."""

from __future__ import annotations

import dataclasses
import math

import msgspec
import numpy as np
import pytest

from resource_manager.track.model import TrackModel
from resource_manager.track.observe import TrackTable, bearing_var, feet_ln, visibility_many
from tests.unit.resource_manager.synth import ViewSpec, stack_views, view


def _table(*xy: tuple[float, float], height: float = 1.7) -> TrackTable:
    n = len(xy)
    return TrackTable(
        np.array(xy, dtype=float), np.repeat(np.eye(2)[None] * 0.01, n, 0), np.full(n, height), np.full(n, 0.01)
    )


def test_someone_behind_a_nearer_person_is_hidden_from_a_low_camera_not_from_a_high_one() -> None:
    """Angular silhouettes: at head height the far person's head is covered; from 6 m up it shows."""
    model = TrackModel()
    table = _table((3.0, 0.0), (6.0, 0.0), (3.0, 3.0))
    low, high = visibility_many(
        stack_views([_camera("c", (0.0, 0.0), 1.1), _camera("c", (0.0, 0.0), 6.0)]), table, model, 100.0
    ).p_detect
    assert low[0] == pytest.approx(model.p_detect) and low[2] == pytest.approx(model.p_detect)
    assert low[1] < 0.5  # wholly behind the nearer one
    assert high[1] > 0.7  # mostly visible above the nearer one's head
    far = _table((200.0, 0.0))
    alone = stack_views([_camera("c", (0.0, 0.0), 1.1)])
    assert visibility_many(alone, far, model, 100.0).p_detect[0, 0] == 0.0  # out of range: no evidence either way


def _camera(sid: str, origin: tuple[float, float], z_m: float, body_radius_m: float = 0.0) -> ViewSpec:
    """A camera that sees no blob."""
    return dataclasses.replace(view(sid, origin, [], z=z_m), sigma_rad=0.0035, body_radius_m=body_radius_m)


def test_a_robot_hides_the_feet_of_someone_behind_it_from_a_high_camera_but_not_the_head() -> None:
    """A robot (a 0.18 m cylinder up to its camera at 1.1 m) 3 m from a camera 2.5 m up: the feet of a person
    behind it are hidden from that camera, most of the person is not; someone beside the robot, and the robot's
    own camera, are not affected."""
    model = TrackModel()
    high = _camera("ptz", (0.0, 0.0), 2.5)
    robot = _camera("robot", (3.0, 0.0), 1.1, body_radius_m=0.18)
    behind, beside = (4.5, 0.0), (4.5, 1.5)
    vis = visibility_many(stack_views([high, robot]), _table(behind, beside), model, 100.0)
    assert vis.feet_hidden[0, 0] > 0.5  # the box from the high camera ends at the robot's top
    assert model.p_detect_hidden < vis.p_detect[0, 0] < model.p_detect  # partly covered: still likely seen
    assert vis.feet_hidden[0, 1] == 0.0 and vis.p_detect[0, 1] == pytest.approx(model.p_detect)
    assert vis.feet_hidden[1].max() == 0.0  # a camera's own body hides nothing from it
    alone = visibility_many(stack_views([high]), _table(behind), model, 100.0)
    assert alone.feet_hidden[0, 0] == 0.0  # without the robot among the views, nothing hides them


def test_a_box_cut_by_a_robot_reads_no_farther_than_where_its_top_meets_the_floor() -> None:
    """The robot's top (1.1 m) 3 m from a camera 2.5 m up: its line of sight meets the floor 2.5·3/1.4 m away, so
    a box of the person behind it cut there reads at most that far; someone nobody covers has no bound."""
    model = TrackModel()
    high = _camera("ptz", (0.0, 0.0), 2.5)
    robot = _camera("robot", (3.0, 0.0), 1.1, body_radius_m=0.18)
    vis = visibility_many(stack_views([high, robot]), _table((4.5, 0.0), (4.5, 1.5)), model, 100.0)
    assert vis.cut_reach_m[0, 0] == pytest.approx(2.5 * 3.0 / 1.4, rel=1e-6)
    assert vis.cut_reach_m[0, 1] == 0.0  # nothing covers the feet of the one beside


def test_a_distance_beyond_what_the_cover_allows_is_not_explained_by_a_cut() -> None:
    """A reading 0.4 m farther than predicted, 0.1 m σ: with the cover's top bounding the cut to 0.5 m farther, a
    cut box explains it better than the diffuse model does, and a reading 2 m farther is no cut at all."""
    var = np.array([0.01, 0.01])
    dist, cut = np.array([6.0, 6.0]), np.array([0.5, 0.5])
    nu = np.array([0.4, 2.0])
    _, diffuse = feet_ln(nu, var, dist, cut, (0.05, 4.0))
    _, bounded = feet_ln(nu, var, dist, cut, (0.05, 4.0), reach=np.array([6.5, 6.5]))
    assert bounded[0] > diffuse[0] + 1.0
    assert bounded[1] == -np.inf and np.isfinite(diffuse[1])
    _, none = feet_ln(nu, var, dist, cut, (0.05, 4.0), reach=np.array([0.0, np.inf]))
    np.testing.assert_allclose(none, diffuse)  # no cover bound: the diffuse model


def test_a_view_whose_blobs_merge_knows_the_foot_of_the_nearest_person_in_front() -> None:
    """Two people on one bearing, 3 m and 4.5 m from a camera 2.5 m up: where the camera's blobs are foreground
    segments, a blob of the far one may end at the near one's feet, 3 m away; a person detector's boxes may not, and
    nothing is in front of the near one or of someone off the bearing."""
    model = TrackModel()
    table = _table((3.0, 0.0), (4.5, 0.0), (4.5, 2.0))
    merging = dataclasses.replace(_camera("seg", (0.0, 0.0), 2.5), blobs_merge=True)
    boxes = _camera("det", (0.0, 0.0), 2.5)
    vis = visibility_many(stack_views([merging, boxes]), table, model, 100.0)
    assert vis.cover_near_m[0, 1] == pytest.approx(3.0, rel=1e-6)
    assert vis.cover_near_m[0, 0] == 0.0 and vis.cover_near_m[0, 2] == 0.0
    assert vis.cover_near_m[1].max() == 0.0
    assert vis.feet_hidden[1, 1] == pytest.approx(vis.feet_hidden[0, 1])  # the same cover, whatever the sensor
    # A camera's body in front hides the feet too, but no foreground blob takes it in (it is background).
    robot = _camera("robot", (3.0, 0.0), 1.1, body_radius_m=0.18)
    behind_robot = visibility_many(stack_views([merging, robot]), _table((4.5, 0.0)), model, 100.0)
    assert behind_robot.feet_hidden[0, 0] > 0.5 and behind_robot.cover_near_m[0, 0] == 0.0


def test_a_distance_nearer_than_the_person_is_a_merged_blob_only_down_to_the_covers_foot() -> None:
    """A person predicted 6 m away behind someone 5 m away, a reading 0.9 m nearer (0.05 m σ): a blob that took the
    nearer one in explains it, and far better than the feet do; a reading 2 m nearer (beyond the cover's foot) is
    no such blob, and without a merging cover nothing changes."""
    var = np.array([0.0025, 0.0025])
    dist, cut = np.array([6.0, 6.0]), np.array([0.3, 0.3])
    nu = np.array([-0.9, -2.0])
    feet, plain = feet_ln(nu, var, dist, cut, (0.05, 4.0))
    _, merged = feet_ln(nu, var, dist, cut, (0.05, 4.0), near=np.array([5.0, 5.0]))
    assert merged[0] > feet[0] + 5.0 and plain[0] == -np.inf
    assert merged[1] == -np.inf
    _, none = feet_ln(nu, var, dist, cut, (0.05, 4.0), near=np.zeros(2))
    np.testing.assert_allclose(none, plain)
    # Where a merging cover stands, a reading farther than predicted keeps half of the cut box's share.
    far = np.array([0.4, 0.4])
    _, cut_only = feet_ln(far, var, dist, cut, (0.05, 4.0))
    _, shared = feet_ln(far, var, dist, cut, (0.05, 4.0), near=np.array([5.0, 0.0]))
    assert shared[0] == pytest.approx(cut_only[0] + math.log(0.5)) and shared[1] == pytest.approx(cut_only[1])


def test_bearing_variance_falls_to_the_sensors_own_with_distance() -> None:
    views = stack_views([dataclasses.replace(view("a", (0.0, 0.0), []), point_var_m2=0.01)])
    var = bearing_var(views, np.zeros(3, np.int64), np.array([1.0, 4.0, 1e6]))
    assert var[0] > var[1] > var[2]
    assert var[2] == pytest.approx(math.radians(0.2) ** 2)
    assert var[0] == pytest.approx(math.radians(0.2) ** 2 + 0.01)  # the point's spread seen from 1 m


def test_each_view_scores_its_blobs_against_its_own_place_of_a_track() -> None:
    """A table with a place per view: p1 looks for the track at its person, p2 one metre off. p1's blob scores as
    against a table of that one place; p2's, as against a table of the other."""
    from resource_manager.track.observe import Looks, score_views
    from resource_manager.track.state import TrackRecord

    person = (3.0, 2.0, 1.7, 0)
    views = stack_views([dataclasses.replace(view(s, o, [person]), point_var_m2=0.01)
                         for s, o in (("p1", (0.0, 0.0)), ("p2", (8.0, 0.0)))])  # fmt: skip
    at, off = _table((3.0, 2.0)), _table((3.0, 3.0))
    per_view = TrackTable(np.stack([at.xy, off.xy]), np.stack([at.pos_cov, off.pos_cov]), at.height, at.height_var)
    model, tracks = TrackModel(), [TrackRecord(serial=1, born_ns=0)]

    def scored(table: TrackTable) -> list[float]:
        vis = visibility_many(views, at, model, 50.0)
        looks = Looks.of(tracks, views, model.look_min_s)
        return [float(sc.ln_lr[0, 0]) for sc in score_views(views, views.every(), tracks, table, vis, model=model,
                                                             max_range_m=50.0, looks=looks)]  # fmt: skip

    (p1, p2), (p1_at, _), (_, p2_off) = scored(per_view), scored(at), scored(off)
    assert per_view.n == 1
    assert p1 == pytest.approx(p1_at) and p2 == pytest.approx(p2_off)
    assert p1 > p2


def test_a_multi_view_detector_s_view_finds_a_person_behind_someone_nearer() -> None:
    """A camera at head height with someone wholly covered behind a nearer person: its own detector is unlikely to
    box them; a multi-view detector, which finds people on the floor and draws them into its views, is not."""
    model = TrackModel()
    table = _table((3.0, 0.0), (6.0, 0.0))
    own = _camera("c", (0.0, 0.0), 1.1)
    shared = dataclasses.replace(own, sensor_id="d", shared_detector="mv")
    p = visibility_many(stack_views([own, shared]), table, model, 100.0).p_detect
    assert p[0, 1] < 0.5 and p[1, 1] == pytest.approx(model.p_detect)
    assert p[0, 0] == pytest.approx(p[1, 0])  # nobody in front: alike


def test_a_box_cut_above_the_feet_with_nobody_in_front_is_weighed_not_gated_away() -> None:
    """Something the tracker does not know of (a table, a bag) cuts a box above the feet: its bottom reads 1.5 m
    farther than the person stands, with nobody predicted in front. The blob stays the person's candidate, scored
    below an uncut one and above nothing; a model that says no box is ever so cut gates it out."""
    from resource_manager.track.observe import Looks, score_views
    from resource_manager.track.state import TrackRecord

    person = (4.0, 0.0, 1.7, None)
    fits = dataclasses.replace(view("c", (0.0, 0.0), [person], z=2.5, feet_sigma_m=0.1), sigma_rad=0.0035)
    assert fits.mono_range_m is not None
    cut = dataclasses.replace(fits, mono_range_m=fits.mono_range_m + 1.5)
    table, tracks = _table((4.0, 0.0)), [TrackRecord(serial=1, born_ns=0)]

    def scored(spec: ViewSpec, model: TrackModel) -> float:
        views = stack_views([spec])
        vis = visibility_many(views, table, model, 50.0)
        assert vis.feet_hidden[0, 0] == 0.0  # nobody in front
        looks = Looks.of(tracks, views, model.look_min_s)
        (sc,) = score_views(views, views.every(), tracks, table, vis, model=model, max_range_m=50.0, looks=looks)
        return float(sc.ln_lr[0, 0])

    model = TrackModel()
    assert math.isfinite(scored(cut, model))
    assert scored(cut, model) < scored(fits, model)
    never_cut = msgspec.structs.replace(model, feet_hidden_prob=0.0)
    assert scored(cut, never_cut) == -math.inf
    assert math.isfinite(scored(fits, never_cut))
