"""Connected regions: the same count, labels and statistics as OpenCV's connectedComponentsWithStats."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from sensor_node.components import ColumnRuns, components, packed_components


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


@pytest.mark.parametrize("seed", range(8))
def test_packed_labelling_gives_the_regions_in_the_same_order(seed: int) -> None:
    """Regions in column runs far apart, labelled side by side: the same count and statistics, row by row,
    as labelling the whole mask (odd and even gaps, runs at the mask's edges)."""
    rng = np.random.default_rng(seed)
    mask = np.zeros((81, 540), np.uint8)
    for _ in range(10):
        x, y = int(rng.integers(0, 530)), int(rng.integers(0, 70))
        w, h = int(rng.integers(1, 12)), int(rng.integers(1, 30))
        mask[y : y + h, x : x + w] = np.where(rng.random(mask[y : y + h, x : x + w].shape) < 0.5, 255, 0)
    mask[40:45, 0:2] = mask[10:12, 537:540] = 255
    n, _, stats = components(mask)
    n_packed, stats_packed = packed_components(mask)
    assert ColumnRuns(mask, 1).apart
    assert n_packed == n and np.array_equal(stats_packed, stats)
