"""Colour looks: Bhattacharyya coefficients of square-rooted histograms, and their mean over comparable pairs."""

from __future__ import annotations

import numpy as np
import pytest

from resource_manager.track.looks import bhattacharyya, mean_similarity


def _sqrt_hist(*counts: float) -> np.ndarray:
    h = np.array(counts, dtype=np.float64)
    return np.sqrt(h / h.sum())


def test_bhattacharyya_is_one_for_the_same_colours_zero_for_disjoint_nan_when_incomparable() -> None:
    red, blue, half = _sqrt_hist(1, 0, 0, 0), _sqrt_hist(0, 0, 1, 0), _sqrt_hist(1, 0, 1, 0)
    bc = bhattacharyya(np.array([red, blue]), [red, blue, half, None, np.ones(3)])
    assert bc.shape == (2, 5)
    assert bc[0, 0] == pytest.approx(1.0) and bc[1, 1] == pytest.approx(1.0)
    assert bc[0, 1] == pytest.approx(0.0) and bc[1, 0] == pytest.approx(0.0)
    assert bc[0, 2] == pytest.approx(np.sqrt(0.5))
    assert np.isnan(bc[:, 3]).all() and np.isnan(bc[:, 4]).all()  # no look; a look of another length
    assert bhattacharyya(red, [red]).shape == (1, 1)


def test_mean_similarity_skips_pairs_it_cannot_compare() -> None:
    red, blue = _sqrt_hist(1, 0, 0, 0), _sqrt_hist(0, 0, 1, 0)
    assert mean_similarity([(red, red), (red, blue), (None, red), (red, np.ones(2))]) == pytest.approx(0.5)
    assert mean_similarity([(None, red)]) is None
