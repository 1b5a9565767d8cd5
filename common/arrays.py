"""Array type aliases, defined once: numpy arrays of the element types the project passes around."""

from __future__ import annotations

import functools
from typing import Any

import numpy as np
import numpy.typing as npt

__all__ = ["BoolArray", "Float32Array", "FloatArray", "Image", "IntArray", "Mask", "U8Image", "pairs_of"]

FloatArray = npt.NDArray[np.float64]
"""float64 values: coordinates, angles, costs."""
Float32Array = npt.NDArray[np.float32]
"""float32 values: images' working copies and per-pixel maps."""
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]
"""Masks."""
U8Image = npt.NDArray[np.uint8]
"""An 8-bit image (grey or BGR)."""
Image = npt.NDArray[Any]
"""An image of any element type (uint8 grey or BGR, float32 working copies)."""
Mask = npt.NDArray[Any]
"""A mask: bool, or uint8 0/255 as OpenCV makes them."""


@functools.cache
def pairs_of(n: int) -> tuple[npt.NDArray[np.intp], npt.NDArray[np.intp]]:
    """The (i, j), i < j, of ``n`` items in the order of ``itertools.combinations`` (read-only, cached)."""
    ia, ib = np.triu_indices(n, 1)
    ia.flags.writeable = ib.flags.writeable = False
    return ia, ib
