"""Head extraction: the topmost part of the blob at 3:2, not the body centroid."""

from __future__ import annotations

import numpy as np
import pytest

from sensor_node.head import extract_head


@pytest.mark.parametrize(("arm", "body_row"), [(False, 15), (True, 15), (False, 13)])
def test_head_centroid_not_body_centroid(arm: bool, body_row: int) -> None:
    m = np.zeros((100, 40), bool)
    m[0:15, 20:30] = True  # head: columns 20..29, centre 24.5
    m[body_row:100, 5:35] = True  # body: centre 19.5 (row 13: shoulders inside the 3:2 head box)
    if arm:
        m[30:60, 0:5] = True  # an arm stretched out on one side moves the body centroid, not the head
    head = extract_head(m, head_ratio=1.5)
    assert head.u_px == pytest.approx(24.5, abs=0.3)
    assert head.top_px == 0
    assert head.width_px == 10 and head.height_px == 15
    assert float(np.nonzero(m)[1].mean()) < 20.0


def test_empty_mask_is_an_error() -> None:
    with pytest.raises(ValueError):
        extract_head(np.zeros((10, 10), bool))


@pytest.mark.parametrize("centre", [24.0, 24.3, 24.75])
def test_sub_pixel_head_edges_from_partly_covered_pixels(centre: float) -> None:
    # A head 9.4 px wide whose left side contrasts strongly with the wall (hair: -120 grey levels)
    # and its right side weakly (face: +24). Edge pixels carry the covered fraction of that contrast;
    # the threshold (16) keeps a partly covered hair pixel but drops a partly covered face pixel.
    half = 4.7
    cols = np.arange(-1, 41)  # the diff has one extra column each side of the 40-column box
    cover = np.clip(np.minimum(cols + 0.5, centre + half) - np.maximum(cols - 0.5, centre - half), 0.0, 1.0)
    contrast = np.where(cols < centre, -120.0, 24.0)
    diff_row = cover * contrast
    diff = np.tile(diff_row, (40, 1))
    diff[15:] = 0.0
    m = np.abs(diff[:, 1:-1]) > 16
    m[15:40, 14:36] = True  # the body below
    plain = extract_head(m, head_ratio=1.5)
    sub = extract_head(m, head_ratio=1.5, diff=lambda r0, r1: diff[r0:r1].astype(np.float32))
    assert sub.u_px == pytest.approx(centre, abs=0.05)
    # The mask alone rounds to whole pixels and loses the faint side: up to ~0.5 px off.
    assert abs(plain.u_px - centre) >= 0.2
