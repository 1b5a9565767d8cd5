"""Step 2's Eq. (7) matrices of one tick: each camera pair matched once, with the temporal term of the tracks.

Several tracks try the same camera pair in one tick; :class:`PairMatches` scores each pair's blobs once
(:func:`~resource_manager.match.match_matrices`, the pairs every track tries first in one vectorised pass) and
keeps the matcher's accepted pairs. The temporal term c_t is 1 where a pair of blobs continues a track's
previous correspondence (the same node-side blob ids), plus the positional term near a track's prediction.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from resource_manager.match import Matcher, MatchMatrix, MatchParams, ViewBlobs, match_matrices
from resource_manager.track import TrackRecord

__all__ = ["PairMatch", "PairMatches", "temporal_links"]

FloatArray = npt.NDArray[np.float64]


@dataclass(slots=True)
class PairMatch:
    mm: MatchMatrix
    pairs: dict[int, int]
    """row -> column of the accepted matches."""


def temporal_links(a: ViewBlobs, b: ViewBlobs, tracks: list[TrackRecord]) -> FloatArray:
    """c_t: 1 where the pair continues a track's previous correspondence (same node blob ids)."""
    temporal = np.zeros((a.n, b.n))
    if a.n and b.n:
        rows = {int(lid): i for i, lid in enumerate(a.local_id)}
        cols = {int(lid): j for j, lid in enumerate(b.local_id)}
        for tr in tracks:
            la, lb = tr.links.get(a.sensor_id), tr.links.get(b.sensor_id)
            if la in rows and lb in cols:
                temporal[rows[la], cols[lb]] = 1.0
    return temporal


class PairMatches:
    """The Eq. 7 matches of the camera pairs tried in one tick (built per tick: tracks move between ticks)."""

    def __init__(
        self,
        views: dict[str, ViewBlobs],
        tracks: list[TrackRecord],
        params: MatchParams,
        matcher: Matcher,
        threshold: float,
    ) -> None:
        self.views = views
        self.tracks = tracks
        self.params = params
        self.matcher = matcher
        self.threshold = threshold
        self.txy = np.array([tr.x[:2] for tr in tracks]).reshape(-1, 2)
        self.cache: dict[tuple[str, str], PairMatch] = {}

    def prefetch(self, keys: set[tuple[str, str]]) -> None:
        """Eq. 7 for every pair (sorted sensor ids) some track will try first, in one vectorised pass."""
        todo = sorted(k for k in keys if k not in self.cache)
        if todo:
            self._match(todo)

    def get(self, a_id: str, b_id: str) -> PairMatch:
        """The match of cameras ``a_id`` < ``b_id`` (computed on first use)."""
        key = (a_id, b_id)
        got = self.cache.get(key)
        return got if got is not None else self._match([key])[0]

    def _match(self, keys: list[tuple[str, str]]) -> list[PairMatch]:
        pairs = [(self.views[a], self.views[b]) for a, b in keys]
        temporals = [temporal_links(a, b, self.tracks) for a, b in pairs]
        mms = match_matrices(pairs, self.params, temporals, self.threshold, self.txy)
        out = [PairMatch(mm, dict(self.matcher.match(mm.r, self.threshold))) for mm in mms]
        self.cache.update(zip(keys, out, strict=True))
        return out
