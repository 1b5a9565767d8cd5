"""The tick's views stacked: blobs concatenated in view order, per-view rows, subsets and splits that undo it."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from resource_manager.track.stack import Spread, ViewStack
from tests.unit.resource_manager.synth import view

SPREAD = Spread(cross_var=0.01, range_var=0.04)


def _views() -> list:
    a = view("a", (0.0, 0.0), [(3.0, 1.0, 1.7, 0), (2.0, -2.0, 1.8, 1)])
    b = view("b", (5.0, 5.0), [])
    c = view("c", (6.0, 0.0), [(3.0, 1.0, 1.7, 0), (4.0, 3.0, 1.6, 2), (1.0, 4.0, 1.9, 3)], z=1.4)
    return [a, b, c]


def test_blobs_are_concatenated_in_view_order_with_each_views_rows() -> None:
    views = _views()
    stack = ViewStack.of(views, [SPREAD] * 3)
    assert stack.n_views == 3 and stack.rows == {"a": 0, "b": 1, "c": 2}
    assert stack.offsets.tolist() == [0, 2, 2, 5]
    assert stack.view_of.tolist() == [0, 0, 2, 2, 2]
    assert stack.bearing_rad.tolist() == [*views[0].bearing_rad, *views[2].bearing_rad]
    assert stack.top_elev_rad.tolist() == [*views[0].top_elev_rad, *views[2].top_elev_rad]
    assert stack.origin.tolist() == [[0.0, 0.0], [5.0, 5.0], [6.0, 0.0]]
    assert stack.z_m.tolist() == [1.1, 1.1, 1.4]
    assert np.isnan(stack.mono_range_m).all()  # no view measured feet distances
    assert not stack.top_cut.any()
    assert stack.hist_bins.tolist() == [0, 0, 0] and stack.hist_sqrt == {}  # nor sent square-rooted histograms


def test_views_with_histograms_of_different_sizes_keep_each_size_apart() -> None:
    a = _views()[0]
    small = view("s", (1.0, 1.0), [(2.0, 2.0, 1.7, 0)])
    small = dataclasses.replace(small, hist_sqrt=np.full((1, 8), 8**-0.5))
    a = dataclasses.replace(a, hist_sqrt=np.sqrt(a.hist))
    stack = ViewStack.of([a, small], [SPREAD] * 2)
    assert stack.hist_bins.tolist() == [16, 8]
    assert stack.hist_sqrt[16].shape == (3, 16) and stack.hist_sqrt[8].shape == (3, 8)
    assert stack.hist_sqrt[16][1] == pytest.approx(np.sqrt(a.hist[1]))
    assert not stack.hist_sqrt[16][2].any() and not stack.hist_sqrt[8][:2].any()  # zero outside their views


def test_a_subset_takes_the_chosen_blobs_of_the_chosen_views_and_split_undoes_stacking() -> None:
    views = _views()
    stack = ViewStack.of(views, [SPREAD] * 3)
    sub = stack.subset([2, 0], [[2, 0], [1]])
    assert sub.rows == {"c": 0, "a": 1} and sub.counts.tolist() == [2, 1]
    assert sub.bearing_rad.tolist() == [views[2].bearing_rad[2], views[2].bearing_rad[0], views[0].bearing_rad[1]]
    assert sub.z_m.tolist() == [1.4, 1.1]
    parts = stack.split(np.arange(10.0).reshape(2, 5))
    assert [p.shape for p in parts] == [(2, 2), (2, 0), (2, 3)]
    assert parts[2][1].tolist() == [7.0, 8.0, 9.0]


def test_bearing_variance_falls_to_the_sensors_own_with_distance() -> None:
    stack = ViewStack.of(_views(), [SPREAD] * 3)
    rows = np.zeros(3, np.int64)
    var = stack.bearing_var(rows, np.array([1.0, 4.0, 1e6]))
    assert var[0] > var[1] > var[2]
    assert var[2] == pytest.approx(math.radians(0.2) ** 2)
    assert var[0] == pytest.approx(math.radians(0.2) ** 2 + SPREAD.cross_var)  # spread seen from 1 m
