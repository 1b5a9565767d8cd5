"""The matchers that turn an Eq. 7 confidence matrix into one-to-one blob pairs (chosen by name).

``greedy`` is the paper's: take the largest entry, delete its row and column, repeat. ``global`` maximises the
total confidence (Hungarian) with a private "unmatched" dummy per row and column (docs/geometry.md §4).
Both only pair entries above the threshold tau. :mod:`resource_manager.match` re-exports them.
"""

from __future__ import annotations

from typing import Final, Protocol

import numpy as np
from scipy.optimize import linear_sum_assignment

from common.arrays import FloatArray

__all__ = ["MATCHERS", "GlobalMatcher", "GreedyMatcher", "Matcher", "get_matcher"]


class Matcher(Protocol):
    """Turns a confidence matrix into one-to-one pairs above a threshold."""

    name: str

    def match(self, r: FloatArray, threshold: float) -> list[tuple[int, int]]:
        """Return (row, column) pairs, each row and column at most once, every r > threshold."""
        ...


class GreedyMatcher:
    """The paper's greedy matcher: take the largest entry, delete its row and column, repeat.

    Scanning the remaining (N-k)x(N-k) matrix N times costs Σ m² ≈ N³/3 comparisons; sorting the entries
    above the threshold once and walking them gives the same pairs in O(N² log N).
    """

    name = "greedy"

    def match(self, r: FloatArray, threshold: float) -> list[tuple[int, int]]:
        m = np.asarray(r, dtype=np.float64)
        out: list[tuple[int, int]] = []
        if m.size == 0 or np.isnan(m).any():  # argmax stops at the first NaN: nothing is matched
            return out
        # Same result as rescanning the matrix: the entries above the threshold, largest first (ties in
        # row-major order, as argmax), each taken unless its row or column already was.
        flat = np.flatnonzero(m > threshold)
        order = flat[np.argsort(-m.ravel()[flat], kind="stable")]
        rows_used: set[int] = set()
        cols_used: set[int] = set()
        ncols = m.shape[1]
        for f in order.tolist():
            i, j = divmod(f, ncols)
            if i in rows_used or j in cols_used:
                continue
            out.append((i, j))
            rows_used.add(i)
            cols_used.add(j)
        return out


class GlobalMatcher:
    """Maximise the total confidence (Hungarian), each blob free to stay unmatched.

    The (na+nb) square problem gives every row and column a private dummy worth
    threshold/2, so a real pair is taken only when r > threshold (docs/geometry.md §4).
    """

    name = "global"

    def match(self, r: FloatArray, threshold: float) -> list[tuple[int, int]]:
        na, nb = r.shape
        if na == 0 or nb == 0:
            return []
        forbid = -1e6
        n = na + nb
        w = np.full((n, n), forbid)
        w[:na, :nb] = np.where(r > threshold, r, forbid)
        u = threshold / 2.0
        w[np.arange(na), nb + np.arange(na)] = u
        w[na + np.arange(nb), np.arange(nb)] = u
        w[na:, nb:] = 0.0
        rows, cols = linear_sum_assignment(w, maximize=True)
        return [(int(i), int(j)) for i, j in zip(rows, cols, strict=True) if i < na and j < nb and r[i, j] > threshold]


MATCHERS: Final[dict[str, type[GreedyMatcher] | type[GlobalMatcher]]] = {
    GreedyMatcher.name: GreedyMatcher,
    GlobalMatcher.name: GlobalMatcher,
}
"""Matchers by the name used in ``[manager] matcher``."""


def get_matcher(name: str) -> Matcher:
    """Instantiate a matcher by registry name (KeyError names the choices)."""
    try:
        return MATCHERS[name]()
    except KeyError as err:
        raise KeyError(f"unknown matcher {name!r}; choose from {sorted(MATCHERS)}") from err
