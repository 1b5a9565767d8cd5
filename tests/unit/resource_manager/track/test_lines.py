"""Size-ratio lines (Eq. 2): a measurement along the baseline from two near-colinear views' blob widths."""

from __future__ import annotations

import math

import numpy as np
import pytest

from resource_manager.track.lines import size_ratio_lines

PERSON_WIDTH_M = 0.45


def _slots(
    person: tuple[float, float], cams: list[tuple[float, float]], widen: float = 1.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One track's slots: each camera's bearing to the person and the angular width there of a person-wide
    cylinder (``2 asin(r / d)``, the width Eq. 2 assumes)."""
    origin = np.array([cams], dtype=np.float64)
    blob = []
    for x, y in cams:
        d = math.hypot(person[0] - x, person[1] - y)
        blob.append((math.atan2(person[1] - y, person[0] - x), 2 * math.asin(PERSON_WIDTH_M / (2 * d))))
    blob_a = np.array([blob])
    blob_a[0, 0, 1] *= widen
    return origin, blob_a, np.ones((1, len(cams)), dtype=bool)


def test_a_person_beyond_both_cameras_on_their_line_is_placed_along_it() -> None:
    rows, valid = size_ratio_lines(*_slots((5.0, 0.0), [(0.0, 0.0), (3.0, 0.0)]), width_rel_sigma=0.05)
    assert rows.shape == (1, 1, 4) and valid.tolist() == [[True]]
    ux, uy, value, var = rows[0, 0]
    assert (ux, uy) == pytest.approx((1.0, 0.0)) and value == pytest.approx(5.0, abs=1e-9)
    assert math.sqrt(var) == pytest.approx(2 * 0.05 * 5.0 * 2.0 / 3.0)  # 2 eps D1 D2 / B


@pytest.mark.parametrize(
    ("person", "widen"),
    [
        ((1.5, 3.0), 1.0),  # far off the baseline: the bearings say where the person is
        ((5.0, 0.0), 2.5),  # the first view's blob is a merged group: no width to use
    ],
)
def test_no_line_off_the_baseline_or_from_a_merged_blob(person: tuple[float, float], widen: float) -> None:
    rows, valid = size_ratio_lines(*_slots(person, [(0.0, 0.0), (3.0, 0.0)], widen), width_rel_sigma=0.05)
    assert not valid.any() and rows.shape[1] == 0


def test_one_view_gives_no_pair() -> None:
    rows, valid = size_ratio_lines(*_slots((5.0, 0.0), [(0.0, 0.0)]), width_rel_sigma=0.05)
    assert rows.shape == (1, 0, 4) and valid.shape == (1, 0)
