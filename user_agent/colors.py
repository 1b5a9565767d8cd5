"""One colour per id, the same in the plot, the live view and Foxglove."""

from __future__ import annotations

import colorsys
import zlib

__all__ = ["id_color", "id_color_bgr"]

_GOLDEN = 0.618033988749895


def id_color(ident: str) -> tuple[float, float, float]:
    """A saturated RGB colour in [0, 1]^3, stable for an id across runs and processes."""
    h = (zlib.crc32(ident.encode()) * _GOLDEN) % 1.0
    r, g, b = colorsys.hsv_to_rgb(h, 0.85, 0.9)
    return (r, g, b)


def id_color_bgr(ident: str) -> tuple[int, int, int]:
    """The same colour as 8-bit BGR, for OpenCV drawing."""
    r, g, b = id_color(ident)
    return (round(b * 255), round(g * 255), round(r * 255))
