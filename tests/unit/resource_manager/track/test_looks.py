"""Colour looks: Bhattacharyya coefficients of square-rooted histograms, and two tracks' looks as evidence."""

from __future__ import annotations

import numpy as np
import pytest

from resource_manager.track.looks import bhattacharyya, looks_ln_odds


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


def test_two_tracks_looks_are_evidence_only_where_both_were_learnt_long_enough() -> None:
    red, blue = _sqrt_hist(1, 0, 0, 0), _sqrt_hist(0, 0, 1, 0)

    def odds(a: dict[str, np.ndarray], b: dict[str, np.ndarray], b_s: float = 1.0) -> float | None:
        return looks_ln_odds(
            a, dict.fromkeys(a, 1.0), b, dict.fromkeys(b, b_s), sigma=0.15, outlier_prob=0.05, min_s=0.5
        )

    same, other = odds({"c1": red, "c2": blue}, {"c1": red, "c2": blue}), odds({"c1": red}, {"c1": blue})
    assert same is not None and other is not None and same > 0 > other
    assert odds({"c1": red}, {"c2": red}) is None  # no view in common: colour cannot tell
    assert odds({"c1": red}, {"c1": red}, b_s=0.1) is None  # a look learnt too briefly
