"""Blobs: grouping nearby regions (also across the panorama seam) and validation."""

from __future__ import annotations

import numpy as np
import pytest

from sensor_node.config import PipelineSettings
from sensor_node.segmentation.blobs import find_blobs, roi

H, W = 162, 1080


def _mask(*boxes: tuple[int, int, int, int]) -> np.ndarray:
    m = np.zeros((H, W), np.uint8)
    for u0, v0, w, h in boxes:
        m[v0 : v0 + h, u0 : u0 + w] = 255
    return m


def test_two_people_two_blobs() -> None:
    fg = _mask((100, 40, 20, 100), (400, 50, 20, 90))
    blobs = find_blobs(fg, PipelineSettings())
    assert sorted((b.u0, b.w) for b in blobs) == [(100, 20), (400, 20)]
    assert all(b.changed_frac == pytest.approx(1.0) for b in blobs)


def test_split_body_merges_when_nearby_only() -> None:
    s = PipelineSettings(merge_gap_px=[4, 8])
    fg = _mask((100, 40, 10, 15), (98, 60, 16, 80))  # head and body 5 rows apart
    (b,) = find_blobs(fg, s)
    assert (b.u0, b.v0, b.w, b.h) == (98, 40, 16, 100)
    fg = _mask((100, 20, 10, 15), (98, 60, 16, 80))  # 25 rows apart: separate
    assert len(find_blobs(fg, s)) == 2


def test_blob_across_the_seam_is_one_blob() -> None:
    fg = _mask((1070, 40, 10, 100), (0, 40, 8, 100))
    (b,) = find_blobs(fg, PipelineSettings())
    assert (b.u0, b.w, b.h) == (1070, 18, 100)
    assert b.mask.all()
    assert roi(fg, b.u0, b.v0, b.w, b.h).shape == (100, 18)
    # Without wrap (a perspective image) the two halves stay apart.
    assert len(find_blobs(fg, PipelineSettings(), wrap=False)) == 2


def test_noise_and_sparse_regions_are_rejected() -> None:
    rng = np.random.default_rng(0)
    fg = ((rng.random((H, W)) < 0.002) * 255).astype(np.uint8)  # salt noise
    assert find_blobs(fg, PipelineSettings()) == []
    # Specks spread over a large box merge but fail the changed-fraction test.
    sparse = np.zeros((H, W), np.uint8)
    for k in range(12):
        sparse[40 + 8 * k : 43 + 8 * k, 200 + 5 * k : 203 + 5 * k] = 255
    assert find_blobs(sparse, PipelineSettings(min_component_px=4, min_blob_px=20)) == []
    assert len(find_blobs(sparse, PipelineSettings(min_component_px=4, min_blob_px=20, min_changed_frac=0.0))) == 1


def test_small_blob_rejected() -> None:
    fg = _mask((100, 40, 5, 5))
    assert find_blobs(fg, PipelineSettings()) == []


@pytest.mark.parametrize(
    ("bridge", "joined"),
    [
        ([(104, 56, 1, 4), (105, 62, 1, 6), (100, 70, 1, 3)], True),  # a 1-px neck and shoulder outline
        ([(104, 56, 1, 3)], False),  # 14 rows of nothing on the way down: apart
        ([(140, 56, 1, 20)], False),  # beside them, not in the columns they share
        ([], False),
    ],
)
def test_a_head_joins_the_body_below_through_the_pixels_the_vote_erased(
    bridge: list[tuple[int, int, int, int]], joined: bool
) -> None:
    # Head rows 40-54, body from row 74: 19 rows apart, more than merge_gap_px (8).
    fg = _mask((100, 40, 10, 15), (94, 74, 22, 70))
    before_vote = np.maximum(fg, _mask(*bridge)) if bridge else fg
    blobs = find_blobs(fg, PipelineSettings(merge_gap_px=[4, 8]), links=before_vote)
    assert len(blobs) == (1 if joined else 2)
    assert len(find_blobs(fg, PipelineSettings(merge_gap_px=[4, 8]))) == 2  # without links: apart
