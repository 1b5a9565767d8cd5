"""Per-view tables for Eq. (7): views padded to one blob count, and the colour factor r_is of every pair at once."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from resource_manager.stereo.match_tables import Tables, colour_table
from resource_manager.views.blobs import ViewBlobs
from tests.unit.resource_manager.synth import view

PEOPLE = [(3.0, 1.0, 1.7, 0), (2.0, 4.0, 1.8, 1), (5.0, 3.0, 1.6, 2)]


def _views() -> list[ViewBlobs]:
    return [
        view("a", (0.0, 0.0), PEOPLE),
        view("b", (7.0, 0.0), PEOPLE[::-1]),
        view("c", (0.0, 6.0), PEOPLE[:2]),
        view("d", (7.0, 6.0), []),
    ]


def test_each_views_blobs_fill_its_row_and_the_rest_is_padding() -> None:
    views = _views()
    tabs = Tables(views, 3)
    table = tabs.table([[v.bearing_rad for v in views], [v.width_rad for v in views]])
    assert table.shape == (4, 3, 2)
    for i, v in enumerate(views):
        assert table[i, : v.n, 0].tolist() == v.bearing_rad.tolist()
        assert table[i, : v.n, 1].tolist() == v.width_rad.tolist()
        assert np.isnan(table[i, v.n :]).all()
    flags = tabs.flags([np.array([True, False, True]), None, np.array([False, True]), None])
    assert flags.tolist() == [[True, False, True], [False, False, False], [False, True, False], [False] * 3]


def _index(pairs: list[tuple[ViewBlobs, ViewBlobs]]) -> tuple[Tables, np.ndarray, np.ndarray]:
    uniq: list[ViewBlobs] = []
    for v in (v for pair in pairs for v in pair):
        if all(v is not u for u in uniq):
            uniq.append(v)
    pos = {id(v): i for i, v in enumerate(uniq)}
    ia = np.array([pos[id(a)] for a, _ in pairs], np.int64)
    ib = np.array([pos[id(b)] for _, b in pairs], np.int64)
    return Tables(uniq, 3), ia, ib


def _r_is(pairs: list[tuple[ViewBlobs, ViewBlobs]], use_colour: bool = True) -> np.ndarray:
    tabs, ia, ib = _index(pairs)
    return colour_table(pairs, use_colour, (len(pairs), 3, 3), tabs=tabs, ia=ia, ib=ib)


@pytest.mark.parametrize("with_sqrt", [False, True])
def test_colour_factor_is_a_symmetric_bhattacharyya_coefficient_highest_for_the_same_person(with_sqrt: bool) -> None:
    a, b, c, _ = _views()
    if with_sqrt:  # nodes may send the square roots with the histograms: the same factor
        a, b, c = (dataclasses.replace(v, hist_sqrt=np.sqrt(v.hist)) for v in (a, b, c))
    r = _r_is([(a, b), (b, a), (a, c)])
    assert r[0] == pytest.approx(r[1].T)  # r_is(a_i, b_j) = r_is(b_j, a_i)
    assert ((r >= 0.0) & (r <= 1.0)).all()
    # a's blob i is person i, b's blob j is person 2 - j: the best match of each row is the same person.
    assert r[0].argmax(axis=1).tolist() == [2, 1, 0]
    assert np.diag(r[0][:, ::-1]) == pytest.approx(np.ones(3))  # a histogram against itself: 1
    assert np.diag(r[2])[:2] == pytest.approx(np.ones(2))  # c sees persons 0 and 1 as its blobs 0 and 1
    assert r[2, 0, 1] < 0.5 and r[2, 1, 0] < 0.5


def test_the_stacked_product_for_many_pairs_equals_the_pair_by_pair_one() -> None:
    a, b, c, _ = _views()
    pairs = [(a, b), (b, c), (a, c)]
    many = _r_is(pairs)  # > 2 pairs of one histogram size: one stacked product
    for k, pair in enumerate(pairs):
        assert many[k, : pair[0].n, : pair[1].n] == pytest.approx(_r_is([pair])[0, : pair[0].n, : pair[1].n])


def test_without_colour_or_histograms_the_factor_is_neutral() -> None:
    a, b, c, d = _views()
    assert (_r_is([(a, b), (a, c)], use_colour=False) == 1.0).all()
    bare = dataclasses.replace(b, hist=None)
    assert (_r_is([(a, bare)]) == 1.0).all()
    with_empty = _r_is([(a, b), (b, c), (a, d)])  # a view without blobs (nor histograms) among them
    assert with_empty[0] == pytest.approx(_r_is([(a, b)])[0])
    assert with_empty[1, :3, :2] == pytest.approx(_r_is([(b, c)])[0, :3, :2])
