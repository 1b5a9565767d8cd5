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
