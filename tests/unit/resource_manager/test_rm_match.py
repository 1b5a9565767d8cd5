"""Eq. (7) match measures and the two matchers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from resource_manager.match import (
    MATCHERS,
    GlobalMatcher,
    GreedyMatcher,
    MatchParams,
    ViewBlobs,
    get_matcher,
    match_matrix,
)
from tests.unit.resource_manager.synth import colour_hist


def view(
    sid: str, origin: tuple[float, float], targets: list[tuple[float, float, float, int]], z: float = 1.1
) -> ViewBlobs:
    """Blobs seen from ``origin`` of targets (x, y, height, colour index), exact."""
    o = np.array(origin, dtype=np.float64)
    b, w, top, hist = [], [], [], []
    for x, y, h, k in targets:
        d = math.hypot(x - o[0], y - o[1])
        b.append(math.atan2(y - o[1], x - o[0]))
        w.append(2 * math.atan(0.45 / (2 * d)))
        top.append(math.atan2(h - z, d))
        hist.append(colour_hist(k))
    return ViewBlobs(
        sensor_id=sid,
        origin_xy=o,
        z_m=z,
        sigma_rad=math.radians(0.2),
        bearing_rad=np.array(b),
        width_rad=np.array(w),
        top_elev_rad=np.array(top),
        hist=np.array(hist) if hist else None,
        local_id=np.arange(len(targets)),
    )


@pytest.mark.parametrize(
    ("matcher", "m", "expected"),
    [
        ("greedy", [[0.9, 0.8], [0.85, 0.1]], [(0, 0)]),
        ("global", [[0.9, 0.8], [0.85, 0.1]], [(0, 1), (1, 0)]),
        ("greedy", [[0.05, 0.02], [0.01, 0.09]], []),
        ("global", [[0.05, 0.02], [0.01, 0.09]], []),
        ("greedy", [[0.5, 0.6, 0.1]], [(0, 1)]),
        ("global", [[0.5], [0.6], [0.1]], [(1, 0)]),
        ("greedy", np.zeros((0, 3)), []),
        ("global", np.zeros((2, 0)), []),
    ],
)
def test_matchers_table(matcher: str, m: object, expected: list[tuple[int, int]]) -> None:
    got = get_matcher(matcher).match(np.asarray(m, dtype=np.float64), 0.1)
    assert sorted(got) == expected


def test_registry_names() -> None:
    assert set(MATCHERS) == {"greedy", "global"}
    assert isinstance(get_matcher("greedy"), GreedyMatcher) and isinstance(get_matcher("global"), GlobalMatcher)
    with pytest.raises(KeyError, match="greedy"):
        get_matcher("nope")


@pytest.mark.parametrize("matcher", ["greedy", "global"])
def test_fig6_two_against_three_blobs(matcher: str) -> None:
    """Fig. 6: 2 blobs in Pano 1, 3 in Pano 2; the correct matches are (T1¹, T2²) and (T2¹, T1²)."""
    people = {"A": (2.0, 3.0, 1.80, 1), "B": (4.5, 2.5, 1.65, 2), "C": (3.5, 5.0, 1.70, 3)}
    o1, o2 = (0.0, 0.0), (5.0, 0.0)
    # camera 1 sees A and B (C hidden); camera 2 sees B, A, C (in that blob order)
    v1 = view("p1", o1, [people["A"], people["B"]])
    v2 = view("p2", o2, [people["B"], people["A"], people["C"]])
    mm = match_matrix(v1, v2, MatchParams())
    pairs = sorted(get_matcher(matcher).match(mm.r, 0.1))
    assert pairs == [(0, 1), (1, 0)]
    for i, j in pairs:
        target = [people["A"], people["B"]][i]
        assert np.hypot(*(mm.xy[i, j] - np.array(target[:2]))) < 1e-6


def test_measures_reject_diverging_and_inconsistent_pairs() -> None:
    v1 = view("p1", (0.0, 0.0), [(2.0, 2.0, 1.8, 1)])
    # camera 2 sees a person behind itself: the rays diverge
    v2 = view("p2", (4.0, 0.0), [(6.0, -2.0, 1.8, 1)])
    mm = match_matrix(v1, v2, MatchParams())
    assert mm.parts["r_rc"][0, 0] == 0.0 and mm.r[0, 0] == 0.0
    # same direction but a child-height head in view 2: height consistency drops
    v3 = view("p3", (4.0, 0.0), [(2.0, 2.0, 1.0, 1)])
    assert match_matrix(v1, v3, MatchParams()).parts["r_hc"][0, 0] < 0.1
    # different clothes: colour similarity drops
    v4 = view("p4", (4.0, 0.0), [(2.0, 2.0, 1.8, 7)])
    assert match_matrix(v1, v4, MatchParams()).parts["r_is"][0, 0] < 0.5


def test_temporal_term_lifts_only_plausible_pairs() -> None:
    v1 = view("p1", (0.0, 0.0), [(2.0, 2.0, 1.8, 1)])
    v2 = view("p2", (4.0, 0.0), [(2.0, 2.0, 1.8, 1), (6.0, -2.0, 1.8, 1)])
    plain = match_matrix(v1, v2, MatchParams())
    ct = np.array([[1.0, 1.0]])
    lifted = match_matrix(v1, v2, MatchParams(temporal_weight=1.0), ct, threshold=0.1)
    assert lifted.r[0, 0] > plain.r[0, 0] / 2.0 + 0.4  # (r + 1)/2
    assert lifted.r[0, 1] == 0.0  # geometry says no: the track cannot rescue it


def test_colinear_target_uses_size_ratio() -> None:
    """A target on the baseline between the cameras: Eq. 1 is singular, Eq. 2 localises it."""
    v1 = view("p1", (0.0, 0.0), [(3.0, 0.0, 1.8, 1)])
    v2 = view("p2", (5.0, 0.0), [(3.0, 0.0, 1.8, 1)])
    mm = match_matrix(v1, v2, MatchParams())
    assert bool(mm.size_ratio[0, 0])
    assert mm.r[0, 0] > 0.5
    assert abs(mm.d1_m[0, 0] - 3.0) < 0.05


def test_batched_matrices_equal_single_ones() -> None:
    from resource_manager.match import match_matrices

    rng = np.random.default_rng(3)
    people = [(float(rng.uniform(0, 8)), float(rng.uniform(0, 6)), 1.7, k) for k in range(6)]
    views = [view(f"c{k}", o, people[: 2 + k]) for k, o in enumerate([(0.0, 0.0), (8.0, 0.0), (8.0, 6.0), (0.0, 6.0)])]
    pairs = [(views[0], views[1]), (views[2], views[3]), (views[1], views[3]), (views[0], view("e", (4.0, 3.0), []))]
    temporals = [np.eye(a.n, b.n) for a, b in pairs]
    batched = match_matrices(pairs, MatchParams(), temporals, 0.1)
    for (a, b), t, mb in zip(pairs, temporals, batched, strict=True):
        single = match_matrix(a, b, MatchParams(), t, 0.1)
        assert mb.r.shape == (a.n, b.n)
        assert np.allclose(mb.r, single.r) and np.allclose(mb.xy, single.xy)
        assert np.array_equal(mb.size_ratio, single.size_ratio)


def test_head_cut_by_the_image_top_is_only_a_lower_bound() -> None:
    import dataclasses

    # A person 0.9 m from camera a: the panorama (max elevation 20 deg) cuts the head at 20 deg, so the
    # apparent head top is 1.1 + 0.9 tan(20 deg) = 1.43 m for a 1.8 m person.
    person = (1.9, 0.0, 1.8, 0)
    a = view("a", (1.0, 0.0), [person])
    a = dataclasses.replace(a, top_elev_rad=np.array([math.radians(20.0)]))
    b = view("b", (1.9, 3.0), [person])
    p = MatchParams()
    refused = match_matrix(a, b, p).r[0, 0]
    cut = dataclasses.replace(a, top_cut=np.array([True]))
    accepted = match_matrix(cut, b, p).r[0, 0]
    assert refused < 0.2 < 0.5 < accepted  # 0.2: the default tau
    # ... but a lower bound still: a cut top above the other view's head is inconsistent.
    short = view("b", (1.9, 3.0), [(1.9, 0.0, 0.9, 0)])
    assert match_matrix(cut, short, p).r[0, 0] < 0.2
