"""One colour per id: stable, saturated, the same in RGB and in OpenCV's BGR."""

from __future__ import annotations

import colorsys

import pytest

from user_agent.colors import id_color, id_color_bgr


@pytest.mark.parametrize("ident", ["m-1", "m-2", "p1", "north"])
def test_colour_is_stable_saturated_and_bgr_is_the_same_colour(ident: str) -> None:
    rgb = id_color(ident)
    assert rgb == id_color(ident)
    _hue, s, v = colorsys.rgb_to_hsv(*rgb)
    assert s == pytest.approx(0.85) and v == pytest.approx(0.9)
    b, g, r = id_color_bgr(ident)
    assert (r, g, b) == tuple(round(c * 255) for c in rgb)


def test_neighbouring_ids_get_different_colours() -> None:
    colours = {id_color(f"m-{k}") for k in range(1, 21)}
    assert len(colours) == 20
