"""Angles: wrapping, differences and interpolation, one convention for the whole project.

Every wrapped angle is in [-pi, pi): ``(a + pi) mod 2 pi - pi``, numpy's and Python's floor-mod rule,
so pi itself wraps to -pi. Bearings, azimuths, yaws and pans all use these helpers.
"""

from __future__ import annotations

import math
from typing import Any, overload

import numpy as np

from common.arrays import FloatArray

__all__ = ["TWO_PI", "angle_diff", "interp_angle", "wrap_angle"]

TWO_PI = 2.0 * math.pi


def _wrap_scalar(a: float) -> float:
    """:func:`wrap_angle` of one number (a float or a numpy scalar, kept as it is)."""
    return (a + math.pi) % TWO_PI - math.pi


@overload
def wrap_angle(a: float) -> float: ...
@overload
def wrap_angle(a: FloatArray) -> FloatArray: ...
def wrap_angle(a: Any) -> Any:
    """Wrap angle(s) to [-pi, pi). Returns a float for a scalar, an array for an array."""
    if type(a) is float or type(a) is int:  # plain Python numbers: float % is np.mod's rule, ~10x cheaper
        return _wrap_scalar(a)
    shifted = np.asarray(a, dtype=np.float64) + math.pi
    if shifted.size >= _MANY and shifted.min() > -TWO_PI and shifted.max() < 2.0 * TWO_PI:
        return _wrap_near(shifted)
    w = np.mod(shifted, TWO_PI) - math.pi
    return float(w) if np.ndim(w) == 0 else w


_MANY = 512
"""From this many angles on, :func:`wrap_angle` checks whether they lie within one turn of the range first: the
check costs more than ``np.mod`` saves on fewer."""


def _wrap_near(shifted: FloatArray) -> FloatArray:
    """``np.mod(shifted, TWO_PI) - pi`` of values in (-2 pi, 4 pi) (NaN excluded), by adding or taking one turn.

    ``np.mod`` computes a floored quotient beside the remainder; here the result is the same to the bit: for
    ``y`` in [2 pi, 4 pi) the remainder is ``y - TWO_PI``, exact (Sterbenz), and for ``y`` in (-2 pi, 0) it is
    ``fmod(y) + TWO_PI`` with ``fmod(y) = y``, the one rounding np.mod makes too.
    """
    turn = np.where(shifted < 0.0, -TWO_PI, np.where(shifted >= TWO_PI, TWO_PI, 0.0))
    shifted -= turn
    shifted -= math.pi
    return shifted


def angle_diff(a: float, b: float) -> float:
    """``a - b`` along the shorter arc, in [-pi, pi)."""
    return _wrap_scalar(a - b)


def interp_angle(t0: float, a0: float, t1: float, a1: float, t: float) -> float:
    """Angle at ``t`` moving from ``a0`` to ``a1`` along the shorter arc, wrapped to [-π, π).

    E.g. from 179° to −179° passes through 180°, not through 0°.
    """
    step = _wrap_scalar(a1 - a0)
    if t1 == t0:
        return _wrap_scalar(a0 + step)
    return _wrap_scalar(a0 + step * ((t - t0) / (t1 - t0)))
