"""Per-view tables for Eq. (7): views padded to one blob count, and the colour factor r_is of every pair at once."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from resource_manager.stereo.match_tables import Tables, colour_table
from tests.unit.resource_manager.synth import ViewSpec, stack_views, view

PEOPLE = [(3.0, 1.0, 1.7, 0), (2.0, 4.0, 1.8, 1), (5.0, 3.0, 1.6, 2)]


def _specs() -> list[ViewSpec]:
    return [
        view("a", (0.0, 0.0), PEOPLE),
        view("b", (7.0, 0.0), PEOPLE[::-1]),
        view("c", (0.0, 6.0), PEOPLE[:2]),
        view("d", (7.0, 6.0), []),
    ]


def test_each_views_blobs_fill_its_row_and_the_rest_is_padding() -> None:
    specs = _specs()
    views = stack_views(specs)
    every = views.every()
    tabs = Tables(views, [0, 1, 2, 3], [every.part(i) for i in range(4)], 3)
    table = tabs.table([views.bearing_rad, views.width_rad])
    assert table.shape == (4, 3, 2)
    for i, v in enumerate(specs):
        assert table[i, : v.n, 0].tolist() == v.bearing_rad.tolist()
        assert table[i, : v.n, 1].tolist() == v.width_rad.tolist()
        assert np.isnan(table[i, v.n :]).all()
    cut = np.zeros(views.n, dtype=bool)
    cut[[0, 2, 7]] = True  # a's blobs 0 and 2, c's blob 1
    assert tabs.flags(cut).tolist() == [[True, False, True], [False, False, False], [False, True, False], [False] * 3]
    # Only some blobs of a view: b's blob 2 alone, a's blobs 1 and 0 in that order.
    some = Tables(views, [1, 0], [np.array([5]), np.array([1, 0])], 2).table([views.bearing_rad])
    assert some[:, :, 0].tolist()[0][0] == specs[1].bearing_rad[2] and np.isnan(some[0, 1, 0])
    assert some[1, :, 0].tolist() == [specs[0].bearing_rad[1], specs[0].bearing_rad[0]]


def _r_is(specs: list[ViewSpec], pairs: list[tuple[int, int]], use_colour: bool = True) -> np.ndarray:
    """r_is of ``pairs`` of ``specs`` (by index), each view's blobs all of them."""
    views = stack_views(specs)
    used = list(dict.fromkeys(v for pair in pairs for v in pair))
    pos = {v: i for i, v in enumerate(used)}
    tabs = Tables(views, used, [views.every().part(v) for v in used], 3)
    ia = np.array([pos[a] for a, _ in pairs], np.int64)
    ib = np.array([pos[b] for _, b in pairs], np.int64)
    return colour_table(use_colour, (len(pairs), 3, 3), tabs=tabs, ia=ia, ib=ib)


def test_colour_factor_is_a_symmetric_bhattacharyya_coefficient_highest_for_the_same_person() -> None:
    specs = _specs()
    r = _r_is(specs, [(0, 1), (1, 0), (0, 2)])
    assert r[0] == pytest.approx(r[1].T)  # r_is(a_i, b_j) = r_is(b_j, a_i)
    assert ((r >= 0.0) & (r <= 1.0)).all()
    # a's blob i is person i, b's blob j is person 2 - j: the best match of each row is the same person.
    assert r[0].argmax(axis=1).tolist() == [2, 1, 0]
    assert np.diag(r[0][:, ::-1]) == pytest.approx(np.ones(3))  # a histogram against itself: 1
    assert np.diag(r[2])[:2] == pytest.approx(np.ones(2))  # c sees persons 0 and 1 as its blobs 0 and 1
    assert r[2, 0, 1] < 0.5 and r[2, 1, 0] < 0.5


def test_the_stacked_product_for_many_pairs_equals_the_pair_by_pair_one() -> None:
    specs = _specs()
    pairs = [(0, 1), (1, 2), (0, 2)]
    many = _r_is(specs, pairs)  # > 2 pairs of one histogram size: one stacked product
    for k, (a, b) in enumerate(pairs):
        na, nb = specs[a].n, specs[b].n
        assert many[k, :na, :nb] == pytest.approx(_r_is(specs, [(a, b)])[0, :na, :nb])


def test_without_colour_or_histograms_the_factor_is_neutral() -> None:
    specs = _specs()
    assert (_r_is(specs, [(0, 1), (0, 2)], use_colour=False) == 1.0).all()
    bare = [specs[0], dataclasses.replace(specs[1], hist=None)]
    assert (_r_is(bare, [(0, 1)]) == 1.0).all()
    with_empty = _r_is(specs, [(0, 1), (1, 2), (0, 3)])  # a view without blobs (nor histograms) among them
    assert with_empty[0] == pytest.approx(_r_is(specs, [(0, 1)])[0])
    assert with_empty[1, :3, :2] == pytest.approx(_r_is(specs, [(1, 2)])[0, :3, :2])
