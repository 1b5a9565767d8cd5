"""The Bhattacharyya coefficient of square-rooted histograms: 1 for the same colours, 0 for disjoint ones."""

from __future__ import annotations

import numpy as np
import pytest

from common.histograms import bhattacharyya_coefficients, histogram_root

RED = np.array([1.0, 0.0, 0.0, 0.0])
GREEN = np.array([0.0, 1.0, 0.0, 0.0])
MIXED = np.array([0.25, 0.25, 0.25, 0.25])


@pytest.mark.parametrize(
    ("p", "q", "want"),
    [(RED, RED, 1.0), (RED, GREEN, 0.0), (RED, MIXED, 0.5), (MIXED, MIXED, 1.0)],
)
def test_coefficient_of_two_histograms(p: np.ndarray, q: np.ndarray, want: float) -> None:
    got = bhattacharyya_coefficients(histogram_root(p[None]), histogram_root(q[None]))
    assert got.shape == (1, 1)
    assert got[0, 0] == pytest.approx(want)


def test_every_row_against_every_row_and_batched() -> None:
    p = histogram_root(np.stack([RED, GREEN, MIXED]))
    q = histogram_root(np.stack([GREEN, MIXED]))
    table = bhattacharyya_coefficients(p, q)
    assert table.shape == (3, 2)
    assert table == pytest.approx(np.array([[0.0, 0.5], [1.0, 0.5], [0.5, 1.0]]))
    batched = bhattacharyya_coefficients(np.stack([p, p]), np.stack([q, q]))
    assert batched.shape == (2, 3, 2) and (batched == table).all()


def test_negative_bins_count_as_empty_and_rounding_stays_in_range() -> None:
    assert histogram_root(np.array([-1e-9, 0.25])).tolist() == [0.0, 0.5]
    over = np.array([[np.sqrt(0.5 + 1e-9), np.sqrt(0.5 + 1e-9)]])
    assert bhattacharyya_coefficients(over, over)[0, 0] == 1.0
