"""Connected regions: the same count, labels and statistics as OpenCV's connectedComponentsWithStats."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from sensor_node.components import components


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("density", [0.0, 0.02, 0.3, 0.55])  # 3 regions; many
def test_components_match_opencv(seed: int, density: float) -> None:
    rng = np.random.default_rng(seed)
    mask = np.where(rng.random((81, 120)) < density, 255, 0).astype(np.uint8)
    # Rings with islands in their holes, and a region touching the image's edges.
    cv2.rectangle(mask, (10, 10), (40, 40), 255, 3)
    mask[24:27, 24:27] = 255
    mask[0:5, 100:120] = 255
    n, labels, stats = components(mask)
    n_cv, labels_cv, stats_cv, _ = cv2.connectedComponentsWithStats(mask, connectivity=8, ltype=cv2.CV_32S)
    assert n == n_cv
    assert np.array_equal(labels, labels_cv)
    assert np.array_equal(stats[1:], stats_cv[1:])


def test_an_empty_mask_has_only_the_background() -> None:
    n, labels, stats = components(np.zeros((10, 10), np.uint8))
    assert n == 1 and not labels.any() and stats.shape == (1, 5)
