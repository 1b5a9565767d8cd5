"""Localisation of one person from a pair of views (Eq. 1, Eq. 2) and from all views at once."""

from __future__ import annotations

import math

import numpy as np
import pytest

from common.error_model import pair_position_error
from resource_manager.stereo.localize import localize_best_pair, localize_least_squares
from tests.unit.resource_manager.synth import stack_views, view

SIG = math.radians(0.2)


def test_localize_triangulation_covariance_matches_error_model() -> None:
    v1 = view("p1", (0.0, 0.0), [(2.0, 3.0, 1.8, 1)])
    v2 = view("p2", (5.0, 0.0), [(2.0, 3.0, 1.8, 1)])
    m = localize_best_pair(stack_views([v1, v2]), 0, 1, min_sigma_m=0.0)
    assert m is not None and m.method == "triangulation"
    assert np.allclose(m.xy, [2.0, 3.0], atol=1e-9)
    assert m.height_m == pytest.approx(1.8, abs=1e-6)
    predicted = pair_position_error((0, 0), (5, 0), (2, 3), SIG)
    assert math.sqrt(np.trace(m.cov)) == pytest.approx(predicted, rel=1e-6)
    assert m.predicted_error_m == pytest.approx(predicted, rel=1e-6)


def test_size_ratio_refuses_a_blob_wider_than_one_person() -> None:
    """Beyond the second camera, on the camera line, Eq. 2 ranges by the width ratio; a merged group's blob (two
    people wide) would put the fix far along the baseline: no fix from it (twice as wide still picks Eq. 2 by the
    crossover rule, far wider switches to Eq. 1 with its large covariance)."""
    v1 = view("p1", (0.0, 0.0), [(5.0, 0.02, 1.8, 1)])
    v2 = view("p2", (3.0, 0.0), [(5.0, 0.02, 1.8, 1)])
    m = localize_best_pair(stack_views([v1, v2]), 0, 1)
    assert m is not None and m.method == "size_ratio" and m.blobs == (("p1", 0), ("p2", 0))
    assert math.hypot(m.xy[0] - 5.0, m.xy[1] - 0.02) < 0.1
    wide = view("p1", (0.0, 0.0), [(5.0, 0.02, 1.8, 1)])
    wide.width_rad[0] *= 2.0  # 0.9 m at 5 m: by Eq. 2 the person would stand far beyond 5 m
    assert localize_best_pair(stack_views([wide, v2]), 0, 1) is None


def test_localize_least_squares_all_views() -> None:
    vs = [view(f"p{k}", o, [(2.0, 3.0, 1.7, 1)]) for k, o in enumerate([(0.0, 0.0), (5.0, 0.0), (5.0, 6.0)])]
    m = localize_least_squares(stack_views(vs), [0, 1, 2], {})
    assert m is not None and m.method == "least_squares" and np.allclose(m.xy, [2.0, 3.0], atol=1e-6)
    assert len(m.sensors) == 3
