"""clip: one number bounded, NaN kept for the schema to name."""

from __future__ import annotations

import math

import numpy as np
import pytest

from common.numbers import clip


@pytest.mark.parametrize(
    ("x", "want"), [(-2.0, -1.0), (0.5, 0.5), (3.0, 1.0), (-1.0, -1.0), (1.0, 1.0), (np.float64(2.0), 1.0)]
)
def test_clip_bounds_a_number_to_a_python_float(x: float, want: float) -> None:
    got = clip(x, -1.0, 1.0)
    assert got == want and type(got) is float


def test_clip_keeps_nan() -> None:
    assert math.isnan(clip(math.nan, 0.0, 1.0))
