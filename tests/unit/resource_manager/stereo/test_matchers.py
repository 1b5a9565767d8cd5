"""The matchers (resource_manager/stereo/matchers.py): Eq. 7's confidence matrix to one-to-one pairs."""

from __future__ import annotations

import numpy as np
import pytest

from resource_manager.stereo.matchers import MATCHERS, GlobalMatcher, GreedyMatcher, get_matcher


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


def test_both_pair_only_above_the_threshold_and_each_blob_once() -> None:
    rng = np.random.default_rng(1)
    for _ in range(200):
        r = rng.random(tuple(rng.integers(1, 7, 2)))
        for name in MATCHERS:
            pairs = get_matcher(name).match(r, 0.4)
            assert all(r[i, j] > 0.4 for i, j in pairs)
            assert len({i for i, _ in pairs}) == len(pairs) == len({j for _, j in pairs})


def test_greedy_matcher_equals_repeated_argmax() -> None:
    """The sorted walk gives exactly the pairs of the paper's rescan (ties in row-major order, NaN, inf)."""

    def rescan(r: np.ndarray, threshold: float) -> list[tuple[int, int]]:
        m = np.array(r, dtype=np.float64, copy=True)
        out: list[tuple[int, int]] = []
        for _ in range(min(m.shape)):
            i, j = divmod(int(np.argmax(m)), m.shape[1])
            if not m[i, j] > threshold:
                break
            out.append((i, j))
            m[i, :] = -np.inf
            m[:, j] = -np.inf
        return out

    rng = np.random.default_rng(0)
    greedy = GreedyMatcher()
    for k in range(2000):
        r = rng.random(tuple(rng.integers(0, 9, 2)))
        if k % 3 == 0:
            r = np.round(r, 1)  # many ties
        if r.size and k % 50 == 0:
            r.flat[rng.integers(r.size)] = np.nan
        if r.size and k % 7 == 0:
            r.flat[rng.integers(r.size)] = np.inf
        assert greedy.match(r, 0.3) == rescan(r, 0.3)
