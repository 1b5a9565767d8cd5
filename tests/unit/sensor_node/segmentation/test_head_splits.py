"""Splitting a blob that holds several people at the valleys between their heads."""

from __future__ import annotations

import numpy as np
import pytest

from sensor_node.config import PipelineSettings
from sensor_node.features import annotate
from sensor_node.segmentation.blobs import find_blobs
from sensor_node.segmentation.head_splits import split_at_heads, top_profile
from tests.unit.sensor_node.sn_synth import WHITE, ColumnGeometry, H, W, draw_person, mask_of


def _mask(people: list[tuple[float, int]]) -> np.ndarray:
    """Foreground of people drawn at (head column, top row)."""
    img = np.zeros((H, W, 3), np.uint8)
    for u, top in people:
        draw_person(img, u, top=top, shirt=WHITE, head=WHITE)
    return mask_of(img)


def _split(fg: np.ndarray, settings: PipelineSettings) -> list:
    (blob,) = find_blobs(fg, settings)  # grouping merges them into one blob
    return split_at_heads(blob, settings, W)


@pytest.mark.parametrize(
    ("people"), [[(300.0, 40), (318.0, 40)], [(500.0, 30), (521.5, 55)], [(1074.0, 40), (12.0, 44)]]
)
def test_people_side_by_side_are_split_at_the_valley_between_their_heads(people: list[tuple[float, int]]) -> None:
    s = PipelineSettings(split_dip_px=8)
    parts = _split(_mask(people), s)
    assert len(parts) == 2
    heads = sorted((b.u0 + annotate(b, None, ColumnGeometry(), s.head_ratio).head_u_px - b.u0) % W for b in parts)
    assert heads == pytest.approx(sorted(u % W for u, _ in people), abs=1.0)


def test_one_person_is_not_split_by_an_arm_or_a_flat_shoulder() -> None:
    fg = _mask([(400.0, 40)])
    fg[75:120, 384:388] = 255  # an arm held out beside the body, its top a narrow spike below the head
    fg[70:162, 411:424] = 255  # a flat-topped thing (a bag, a ghost) touching them
    s = PipelineSettings(merge_gap_px=[12, 8], split_dip_px=8)
    blobs = find_blobs(fg, s)
    assert len(blobs) == 1
    assert split_at_heads(blobs[0], s, W) == blobs


def test_a_gap_in_the_projection_profile_parts_what_grouping_joined() -> None:
    fg = _mask([(400.0, 40)])
    fg[75:120, 384:388] = 255  # an arm touching the body stays with it
    fg[70:162, 420:440] = 255  # a thing 8 columns away: grouping joins it, the gap parts it again
    fg[100:101, 414] = 255  # a noise speck in the gap does not bridge it
    s = PipelineSettings(merge_gap_px=[12, 8], split_dip_px=8)
    (blob,) = find_blobs(fg, s)
    parts = split_at_heads(blob, s, W)
    assert [(p.u0, p.w) for p in parts] == [(384, 28), (420, 20)]
    head = annotate(parts[0], None, ColumnGeometry(), s.head_ratio)
    assert head.head_u_px == pytest.approx(400.0, abs=0.5)
    # A fragment too small to be a blob stays with its neighbour; off (0) keeps the blob whole.
    fg[70:162, 420:440] = 0
    fg[150:155, 420:424] = 255
    (blob,) = find_blobs(fg, s)
    assert split_at_heads(blob, s, W) == [blob]
    fg[70:162, 420:440] = 255
    (blob,) = find_blobs(fg, s)
    assert split_at_heads(blob, PipelineSettings(merge_gap_px=[12, 8], split_gap_cols=0, split_dip_px=0), W) == [blob]


def test_splitting_off_when_dip_is_zero_and_profile_of_a_blob() -> None:
    fg = _mask([(300.0, 40), (318.0, 40)])
    assert len(_split(fg, PipelineSettings(split_dip_px=0))) == 1  # touching: no gap to part them at
    m = np.zeros((4, 3), bool)
    m[2, 0] = m[1, 2] = True
    assert top_profile(m).tolist() == [2, 4, 1]


def test_a_person_beside_a_sparse_region_survives_the_changed_fraction_check() -> None:
    # A person 6 columns from a wide, sparse region (a ghost's speckle): grouped, the box is mostly
    # empty and fails min_changed_frac; parted first, the person passes it on their own.
    fg = _mask([(400.0, 40)])
    fg[20:162:3, 418:520:3] = 255
    fg[20:162, 418] = 255  # the region's edge column, so the gap is clean
    s = PipelineSettings(merge_gap_px=[12, 8], split_dip_px=8, min_changed_frac=0.3)
    assert find_blobs(fg, s) == []
    (blob,) = find_blobs(fg, s, check_frac=False)
    parts = [p for p in split_at_heads(blob, s, W) if p.changed_frac >= s.min_changed_frac]
    assert len(parts) == 1
    assert annotate(parts[0], None, ColumnGeometry(), s.head_ratio).head_u_px == pytest.approx(400.0, abs=0.5)


def test_an_arm_swung_clear_of_the_body_stays_with_it() -> None:
    # A narrow flat-topped strip 2 columns beside the body (an arm swinging forward, seen from the
    # side): a gap, but no head and much narrower than the body -- not a person of its own.
    fg = _mask([(400.0, 40)])
    fg[62:130, 381:387] = 255
    s = PipelineSettings(merge_gap_px=[12, 8], split_dip_px=8)
    (blob,) = find_blobs(fg, s)
    assert split_at_heads(blob, s, W) == [blob]


def test_an_arm_with_a_ragged_top_beside_the_body_stays_with_it() -> None:
    # An arm one empty column beside the body whose top is ragged (its outer edge column starts
    # lower): on the profile alone its top looks like a head 5 of 6 columns wide; but it is no
    # narrower than the strip below it, so it is no head.
    fg = _mask([(400.0, 40)])
    fg[56:120, 413:419] = 255
    fg[56:66, 418] = 0
    s = PipelineSettings(merge_gap_px=[12, 8], split_dip_px=8)
    (blob,) = find_blobs(fg, s)
    assert split_at_heads(blob, s, W) == [blob]
    # A person there (a head narrower than the body below it) is still parted at the gap.
    fg[56:120, 413:419] = 0
    draw_person_mask = _mask([(400.0, 40), (425.0, 50)])
    (blob,) = find_blobs(draw_person_mask, s)
    assert len(split_at_heads(blob, s, W)) == 2


def test_a_far_person_much_narrower_than_a_near_one_beside_them_is_split_off() -> None:
    # A near person (70 px wide, arms out) with a far one (20 px wide, head lower) touching their side:
    # the far part is under 0.3 of the near one's width, but its head is narrower than its body.
    img = np.zeros((H, W, 3), np.uint8)
    draw_person(img, 400.0, top=20, head_w=14, body_w=70, shirt=WHITE, head=WHITE)
    draw_person(img, 442.0, top=50, head_w=8, body_w=20, shirt=WHITE, head=WHITE)
    fg = mask_of(img)
    s = PipelineSettings()
    parts = _split(fg, s)
    assert len(parts) == 2
    heads = sorted(p.u0 + annotate(p, None, ColumnGeometry(), s.head_ratio).head_u_px - p.u0 for p in parts)
    assert heads == pytest.approx([400.0, 442.0], abs=1.0)
