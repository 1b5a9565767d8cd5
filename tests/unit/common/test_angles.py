"""Angles: one wrap convention ([-pi, pi)), differences along the short arc, interpolation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from common.angles import TWO_PI, angle_diff, interp_angle, wrap_angle


@pytest.mark.parametrize(
    ("a", "expected"),
    [
        (0.0, 0.0),
        (math.pi, -math.pi),
        (-math.pi, -math.pi),
        (3 * math.pi / 2, -math.pi / 2),
        (-7.0, -7.0 + 2 * math.pi),
    ],
)
def test_wrap_angle(a: float, expected: float) -> None:
    assert wrap_angle(a) == pytest.approx(expected, abs=1e-12)
    assert np.allclose(wrap_angle(np.array([a, a])), expected)


def test_wrap_angle_keeps_the_kind_of_its_argument() -> None:
    assert type(wrap_angle(4.0)) is float
    assert type(wrap_angle(np.float64(4.0))) is float
    w = wrap_angle(np.array([4.0, -4.0]))
    assert isinstance(w, np.ndarray) and w.shape == (2,)


@pytest.mark.parametrize(
    ("low", "high"),
    [(-0.5, 0.5), (-3 * math.pi, 3 * math.pi), (-3 * math.pi - 1e-9, 3 * math.pi + 1e-9), (-40.0, 40.0)],
)
def test_wrap_angle_of_many_angles_is_np_mod_to_the_bit(low: float, high: float) -> None:
    """Many angles within a turn of the range take a shortcut past ``np.mod``: the same numbers, edges included."""
    edges = [
        -math.pi,
        math.pi,
        3 * math.pi,
        -3 * math.pi,
        np.nextafter(-3 * math.pi, 0.0),
        np.nextafter(3 * math.pi, 0.0),
    ]
    edges += [np.nextafter(-math.pi, -4.0), np.nextafter(math.pi, 0.0), -math.pi - 1e-17, 0.0, -0.0, TWO_PI, -TWO_PI]
    a = np.concatenate([np.random.default_rng(0).uniform(low, high, (40, 50)).ravel(), edges])
    want = np.mod(a + math.pi, TWO_PI) - math.pi
    got = wrap_angle(a)
    assert np.array_equal(got, want) and np.array_equal(np.signbit(got), np.signbit(want))
    with_nan = a.copy()
    with_nan[7] = math.nan
    assert np.array_equal(wrap_angle(with_nan), np.mod(with_nan + math.pi, TWO_PI) - math.pi, equal_nan=True)


@pytest.mark.parametrize(
    ("a_deg", "b_deg", "want_deg"),
    [(10.0, 30.0, -20.0), (170.0, -170.0, -20.0), (-170.0, 170.0, 20.0), (180.0, 0.0, -180.0), (720.0, 0.0, 0.0)],
)
def test_angle_diff_is_the_short_arc(a_deg: float, b_deg: float, want_deg: float) -> None:
    got = angle_diff(math.radians(a_deg), math.radians(b_deg))
    assert -math.pi <= got < math.pi
    assert got == pytest.approx(math.radians(want_deg), abs=1e-12)
    assert got == pytest.approx(wrap_angle(math.radians(a_deg) - math.radians(b_deg)), abs=0.0)
    assert 2 * math.pi == TWO_PI


@pytest.mark.parametrize(
    ("a0_deg", "a1_deg", "frac", "want_deg"),
    [
        (10.0, 30.0, 0.5, 20.0),
        (170.0, -170.0, 0.5, -180.0),  # across ±180 the short way
        (-170.0, 170.0, 0.25, -175.0),
        (350.0, 10.0, 0.5, 0.0),  # unwrapped inputs are fine
        (0.0, 90.0, 2.0, 180.0 - 360.0),  # extrapolation wraps
        (45.0, 45.0, 0.7, 45.0),
    ],
)
def test_interp_angle_takes_the_short_arc(a0_deg: float, a1_deg: float, frac: float, want_deg: float) -> None:
    got = interp_angle(0.0, math.radians(a0_deg), 1.0, math.radians(a1_deg), frac)
    assert -math.pi <= got < math.pi
    diff = (got - math.radians(want_deg) + math.pi) % (2 * math.pi) - math.pi
    assert abs(diff) < 1e-9
