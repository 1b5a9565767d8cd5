"""The tick's views: every blob of every view in one set of arrays, per-view rows, subsets as index arrays; a
perspective camera's picture."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from resource_manager.views.blobs import ImageBounds, Views
from tests.unit.resource_manager.synth import ViewSpec, stack_views, view


def _specs() -> list[ViewSpec]:
    a = view("a", (0.0, 0.0), [(3.0, 1.0, 1.7, 0), (2.0, -2.0, 1.8, 1)])
    b = view("b", (5.0, 5.0), [])
    c = view("c", (6.0, 0.0), [(3.0, 1.0, 1.7, 0), (4.0, 3.0, 1.6, 2), (1.0, 4.0, 1.9, 3)], z=1.4)
    return [a, b, c]


def test_blobs_lie_view_after_view_with_each_views_rows() -> None:
    specs = _specs()
    views = stack_views(specs)
    assert views.n_views == 3 and views.n == 5 and views.rows == {"a": 0, "b": 1, "c": 2}
    assert views.offsets.tolist() == [0, 2, 2, 5] and views.counts.tolist() == [2, 0, 3]
    assert views.view_of.tolist() == [0, 0, 2, 2, 2]
    assert views.bearing_rad.tolist() == [*specs[0].bearing_rad, *specs[2].bearing_rad]
    assert views.bearing_rad[views.span(2)].tolist() == specs[2].bearing_rad.tolist()
    assert views.entry("c", 1) == 3 and views.local_id[views.entry("c", 1)] == 1
    assert views.origin.tolist() == [[0.0, 0.0], [5.0, 5.0], [6.0, 0.0]]
    assert views.z_m.tolist() == [1.1, 1.1, 1.4]
    assert np.isnan(views.mono_range_m).all() and np.isnan(views.bottom_elev_rad).all()
    assert not views.top_cut.any()
    assert views.hist_bins.tolist() == [16, 0, 16] and set(views.hist_sqrt) == {16}  # b has no blobs: no histograms
    hs = views.hist_of(4)
    assert hs is not None and hs == pytest.approx(np.sqrt(specs[2].hist[2]))  # type: ignore[index]


def test_views_with_histograms_of_different_sizes_keep_each_size_apart() -> None:
    a = _specs()[0]
    small = dataclasses.replace(view("s", (1.0, 1.0), [(2.0, 2.0, 1.7, 0)]), hist=np.full((1, 8), 1.0 / 8))
    views = stack_views([a, small])
    assert views.hist_bins.tolist() == [16, 8]
    assert views.hist_sqrt[16].shape == (3, 16) and views.hist_sqrt[8].shape == (3, 8)
    assert views.hist_sqrt[16][1] == pytest.approx(np.sqrt(a.hist[1]))  # type: ignore[index]
    assert not views.hist_sqrt[16][2].any() and not views.hist_sqrt[8][:2].any()  # zero outside their views


def test_a_subset_is_index_arrays_into_the_views_and_split_undoes_the_stacking() -> None:
    views = stack_views(_specs())
    sub = views.subset(np.array([False, True, True, False, True]))
    assert sub.rows.tolist() == [0, 2]  # only the views with blobs in it
    assert sub.entries.tolist() == [1, 2, 4] and sub.offsets.tolist() == [0, 1, 3] and sub.row_of.tolist() == [0, 1, 1]
    assert sub.part(1).tolist() == [2, 4] and sub.counts.tolist() == [1, 2]
    assert sub.take(views.local_id).tolist() == [1, 0, 2] and sub.pick(views.z_m).tolist() == [1.1, 1.4]
    every = views.every()
    assert every.rows.tolist() == [0, 1, 2] and every.entries.tolist() == [0, 1, 2, 3, 4]
    assert every.take(views.bearing_rad) is views.bearing_rad  # every blob: the arrays as they are, no copy
    parts = every.split(np.arange(10.0).reshape(2, 5))
    assert [p.shape for p in parts] == [(2, 2), (2, 0), (2, 3)]
    assert parts[2][1].tolist() == [7.0, 8.0, 9.0]


@pytest.mark.parametrize(
    ("fov", "width"),
    [(None, 2 * math.pi), ((0.0, 0.5), 1.0), ((math.pi, 4.0), 2 * math.pi)],
)
def test_field_of_view_width(fov: tuple[float, float] | None, width: float) -> None:
    views = stack_views([dataclasses.replace(view("c", (0.0, 0.0), []), fov=fov)])
    assert views.fov_width_rad.tolist() == pytest.approx([width])


def test_no_view() -> None:
    views = Views.empty()
    assert views.n_views == 0 and views.n == 0 and views.every().entries.size == 0


def test_image_bounds_inside_the_picture_and_in_front() -> None:
    # looking along world +x, level: camera x = -world y, camera y = -world z, camera z = world x
    r = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])
    k = np.array([[500.0, 0.0, 320.0], [0.0, 500.0, 240.0], [0.0, 0.0, 1.0]])
    img = ImageBounds(k=k, r=r, t=np.zeros(3), width_px=640, height_px=480)
    pts = np.array([[5.0, 0.0, 0.0], [-5.0, 0.0, 0.0], [5.0, 4.0, 0.0], [5.0, 3.3, 0.0]])
    assert img.inside(pts).tolist() == [True, False, False, False]
    assert img.inside(pts, margin_px=20.0).tolist() == [True, False, False, True]  # u = -10 px
