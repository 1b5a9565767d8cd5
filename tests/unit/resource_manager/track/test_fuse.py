"""The tick's measurement update: slots gather each track's blobs, and fusing them pulls the state to the truth."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from resource_manager.track.fuse import Slots, fuse, fuse_heights
from resource_manager.views.blobs import Views
from tests.unit.resource_manager.synth import stack_views, view

TRUE_A, TRUE_B = (3.0, 2.0, 1.75), (6.0, 4.0, 1.6)


def _stack() -> Views:
    targets = [(*TRUE_A, 0), (*TRUE_B, 1)]
    return stack_views(
        [view("p1", (0.0, 0.0), targets), view("p2", (8.0, 0.0), targets[::-1]), view("p3", (0.0, 6.0), targets)]
    )


def test_slots_index_each_tracks_assigned_blobs_in_the_views() -> None:
    stack = _stack()
    slots = Slots.of([[("p1", 0), ("p2", 1)], [("p3", 1)], []], stack)
    assert slots.shape == (3, 2)
    assert slots.track.tolist() == [0, 0, 1] and slots.slot.tolist() == [0, 1, 0]
    assert slots.view.tolist() == [0, 1, 2]
    assert slots.blob.tolist() == [0, 3, 5]  # p2's blob 1 is the views' entry 2 + 1
    assert stack.bearing_rad[slots.blob[1]] == pytest.approx(math.atan2(TRUE_A[1], TRUE_A[0] - 8.0))
    assert slots.used().tolist() == [[True, True], [True, False], [False, False]]
    assert slots.per_slot(np.array([1.0, 2.0, 3.0]), fill=-1.0).tolist() == [[1.0, 2.0], [3.0, -1.0], [-1.0, -1.0]]


def _prior() -> tuple[np.ndarray, np.ndarray]:
    xs = np.array([[3.5, 1.6, 0.0, 0.0], [5.5, 4.4, 0.0, 0.0]])
    ps = np.stack([np.diag([0.25, 0.25, 0.5, 0.5])] * 2)
    return xs, ps


@pytest.mark.parametrize("line_views", [0, 4])
def test_fusing_the_assigned_bearings_moves_each_track_to_its_person_and_shrinks_its_covariance(
    line_views: int,
) -> None:
    stack = _stack()
    slots = Slots.of([[("p1", 0), ("p2", 1), ("p3", 0)], [("p1", 1), ("p2", 0)]], stack)
    xs, ps = _prior()
    x, p, weight = fuse(
        xs, ps, slots, stack, position_weight=np.ones(3), outlier=(0.05, 10.0), width_rel_sigma=0.15,
        line_views=line_views,
    )  # fmt: skip
    for k, truth in enumerate((TRUE_A, TRUE_B)):
        before = math.hypot(xs[k, 0] - truth[0], xs[k, 1] - truth[1])
        after = math.hypot(x[k, 0] - truth[0], x[k, 1] - truth[1])
        assert after < 0.05 < before
        assert np.trace(p[k, :2, :2]) < 0.1 * np.trace(ps[k, :2, :2])
        assert np.linalg.eigvalsh(p[k]).min() > 0.0  # still a covariance
    assert weight.shape == (2, 3)
    assert weight[0] == pytest.approx([1.0, 1.0, 1.0], abs=0.05)  # exact bearings: none an outlier
    assert weight[1, 2] == 0.0  # the empty slot


def test_a_wrong_blob_among_good_ones_is_weighed_down_as_an_outlier() -> None:
    stack = _stack()
    slots = Slots.of([[("p1", 0), ("p2", 1), ("p3", 1)]], stack)  # p3's blob 1 is the other person
    xs, ps = _prior()
    x, _, weight = fuse(
        xs[:1], ps[:1], slots, stack, position_weight=np.ones(3), outlier=(0.05, 10.0), width_rel_sigma=0.15,
        line_views=0,
    )  # fmt: skip
    assert weight[0, 2] < 0.1 < weight[0, 0]
    assert math.hypot(x[0, 0] - TRUE_A[0], x[0, 1] - TRUE_A[1]) < 0.1


def test_heights_move_to_what_the_views_imply_and_cut_heads_are_left_out() -> None:
    stack = _stack()
    slots = Slots.of([[("p1", 0), ("p3", 0)], [("p2", 0)]], stack)
    xy = np.array([TRUE_A[:2], TRUE_B[:2]])
    height, var = fuse_heights(xy, np.array([1.5, 1.9]), np.array([0.04, 0.04]), slots, stack)
    assert height == pytest.approx([TRUE_A[2], TRUE_B[2]], abs=0.02)
    assert (var < 0.04).all()
    cut = dataclasses.replace(stack, top_cut=np.ones(stack.n, dtype=bool))
    height, var = fuse_heights(xy, np.array([1.5, 1.9]), np.array([0.04, 0.04]), slots, cut)
    assert height.tolist() == [1.5, 1.9] and var.tolist() == [0.04, 0.04]


def test_a_height_far_off_the_track_s_is_left_out_as_an_outlier() -> None:
    """A track known to be 1.75 m tall gets two blobs: one that fits, and one whose top puts the head at 2.6 m (a
    box that took in someone else, raised arms). As an outlier model weighs it, the height stays; trusted, it
    drags."""
    stack = stack_views([view("p1", (0.0, 0.0), [(*TRUE_A, 0)]), view("q", (8.0, 0.0), [(*TRUE_A[:2], 2.6, 0)])])
    slots = Slots.of([[("p1", 0), ("q", 0)]], stack)
    xy, height, var = np.array([TRUE_A[:2]]), np.array([1.75]), np.array([0.05**2])
    robust, robust_var = fuse_heights(xy, height, var, slots, stack, outlier=(0.05, 4.0))
    trusted, _ = fuse_heights(xy, height, var, slots, stack)
    assert robust[0] == pytest.approx(1.75, abs=0.01) and robust_var[0] < var[0]
    assert trusted[0] > 1.85


@pytest.mark.parametrize(("cut", "pulled"), [(0.02, True), (0.5, False)])
def test_a_distance_from_a_box_likely_cut_above_the_feet_does_not_drag_the_track(cut: float, pulled: bool) -> None:
    """Two cameras on one line with the person (their bearings say nothing along it), the nearer one's box 0.5 m
    too far: where something may hide the feet from it, the track stays near its prediction; where nothing does,
    the distance is believed."""
    person = (4.0, 0.0, 1.7, 0)
    near = dataclasses.replace(
        view("ptz", (0.0, 0.0), [person], z=2.5), mono_range_m=np.array([4.5]), mono_sigma_m=np.array([0.05])
    )
    far = view("pano", (-2.0, 0.0), [person])
    stack = stack_views([near, far])
    slots = Slots.of([[("pano", 0), ("ptz", 0)]], stack)
    xs, ps = np.array([[4.0, 0.0, 0.0, 0.0]]), np.diag([0.04, 0.01, 0.25, 0.25])[None]
    x, _, weight = fuse(
        xs, ps, slots, stack, position_weight=np.ones(2), outlier=(0.05, 4.0), width_rel_sigma=0.15, line_views=0,
        feet_cut=np.full((2, 1), cut),
    )  # fmt: skip
    assert bool(x[0, 0] - 4.0 > 0.3) == pulled, x[0, 0]
    assert weight[0].min() > 0.5  # the bearings stay either way


@pytest.mark.parametrize(("cover_m", "pulled"), [(3.0, False), (0.0, True)])
def test_a_blob_that_took_in_a_nearer_person_does_not_pull_the_track_to_them(cover_m: float, pulled: bool) -> None:
    """The demo's case: one camera's foreground blob of a person 4 m away took in the legs of someone standing 3 m
    away in front, so its distance reads 3 m; a second camera looks along the same line (its bearing says nothing
    there). Where the first camera's blobs merge and that person covers the feet, the track stays near its
    prediction; with no such cover, the distance is believed."""
    person = (4.0, 0.0, 1.7, 0)
    near = dataclasses.replace(
        view("seg", (0.0, 0.0), [person], z=2.5), mono_range_m=np.array([3.0]), mono_sigma_m=np.array([0.05])
    )
    stack = stack_views([near, view("pano", (-2.0, 0.0), [person])])
    slots = Slots.of([[("pano", 0), ("seg", 0)]], stack)
    xs, ps = np.array([[4.0, 0.0, 0.0, 0.0]]), np.diag([0.04, 0.01, 0.25, 0.25])[None]
    x, _, weight = fuse(
        xs, ps, slots, stack, position_weight=np.ones(2), outlier=(0.05, 4.0), width_rel_sigma=0.15, line_views=0,
        feet_cut=np.full((2, 1), 0.3), cover_near_m=np.array([[cover_m], [0.0]]),
    )  # fmt: skip
    assert bool(4.0 - x[0, 0] > 0.3) == pulled, x[0, 0]
    assert weight[0].min() > 0.5


@pytest.mark.parametrize("flagged", [True, False])
def test_a_box_the_pictures_side_cuts_is_read_as_part_of_its_person(flagged: bool) -> None:
    """p1's picture ends across the person: its box shows a third of them, on the side of smaller bearings, so its
    centre is off by a third of their width (0.15 m across at 3.6 m). Told so (``side_cut``), the update places
    the person beyond the box's centre, near where p2's ray crosses theirs; not told, it believes the centre (and
    the cut width's size-ratio line)."""
    person = (3.0, 2.0, 1.75, 0)
    p1 = view("p1", (0.0, 0.0), [person])
    whole = float(p1.width_rad[0])
    p1 = dataclasses.replace(
        p1,
        bearing_rad=p1.bearing_rad - whole / 3.0,
        width_rad=np.array([whole / 3.0]),
        side_cut=np.array([1.0 if flagged else 0.0]),
    )
    stack = stack_views([dataclasses.replace(v, point_var_m2=0.01) for v in (p1, view("p2", (8.0, 0.0), [person]))])
    slots = Slots.of([[("p1", 0), ("p2", 0)]], stack)
    xs, ps = np.array([[3.3, 1.7, 0.0, 0.0]]), np.diag([0.25, 0.25, 0.5, 0.5])[None]
    x, _, weight = fuse(
        xs, ps, slots, stack, position_weight=np.ones(2), outlier=(0.05, 10.0), width_rel_sigma=0.15, line_views=4
    )
    err = math.hypot(x[0, 0] - person[0], x[0, 1] - person[1])
    assert (err < 0.1) if flagged else (err > 0.15), err
    assert weight[0].min() > 0.5
