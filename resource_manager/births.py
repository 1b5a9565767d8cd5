"""Step 3 of a tick: new people from the blobs no track explains.

Blobs supporting no track are matched pairwise by Eq. (7) (a bounded number of camera pairs per tick,
round-robin, all their matrices in one vectorised pass); each match is localised (Eq. 1 or Eq. 2) and becomes
a tentative track unless it lies in a track's gate, its feet disagree (:mod:`.mono`), or other cameras that
should see the spot see nothing there (ghost veto); hypotheses seen by more cameras go first.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable

import numpy as np
import numpy.typing as npt

from resource_manager.config import ManagerConfig
from resource_manager.localize import Measurement, localize_best_pair
from resource_manager.match import Matcher, MatchParams, ViewBlobs, match_matrices
from resource_manager.mono import range_mismatch
from resource_manager.track import Tracker
from resource_manager.views import subset_view, wrap

__all__ = ["Births"]

FloatArray = npt.NDArray[np.float64]


class Births:
    """Finds new people among the blobs left over after the tracks took theirs."""

    def __init__(self, config: ManagerConfig, tracker: Tracker, params: MatchParams, matcher: Matcher) -> None:
        self.config = config
        self.tracker = tracker
        self.params = params
        self.matcher = matcher
        self.threshold = config.match.threshold
        self._birth_rr = 0
        self._gates: tuple[FloatArray, FloatArray] | None = None
        self.in_room: Callable[[FloatArray], bool] = lambda _xy: True
        """Whether a position is inside the room (set by the associator): nobody is born outside it."""

    def run(
        self,
        views: dict[str, ViewBlobs],
        used: dict[str, set[int]],
        pose_sigma: dict[str, float],
        t_ns: int,
        agreement_ok: Callable[[Measurement], bool],
    ) -> int:
        """Start tentative tracks from the blobs no track used (``used``: sensor id -> blob indices)."""
        self._gates = None  # track positions have just been updated
        left = {sid: [i for i in range(v.n) if i not in used[sid]] for sid, v in views.items()}
        left = {sid: idx for sid, idx in left.items() if idx}
        if len(left) < 2:
            return 0
        pairs = sorted(itertools.combinations(sorted(left), 2), key=lambda p: -len(left[p[0]]) * len(left[p[1]]))
        budget = self.config.match.max_birth_pairs
        if len(pairs) > budget:
            start = self._birth_rr % len(pairs)
            pairs = (pairs[start:] + pairs[:start])[:budget]
            self._birth_rr += budget
        hyps: list[tuple[int, float, Measurement, dict[str, int]]] = []
        subsets = {sid: subset_view(views[sid], left[sid]) for sid in {s for p in pairs for s in p}}
        matrices = match_matrices([(subsets[a], subsets[b]) for a, b in pairs], self.params, None, self.threshold)
        for (a_id, b_id), mm in zip(pairs, matrices, strict=True):  # all pairs' Eq. 7 in one vectorised pass
            a, b = subsets[a_id], subsets[b_id]
            for ii, jj in self.matcher.match(mm.r, self.threshold):
                meas = localize_best_pair(
                    a,
                    ii,
                    b,
                    jj,
                    sigma_xy_a=pose_sigma.get(a_id, 0.0),
                    sigma_xy_b=pose_sigma.get(b_id, 0.0),
                    width_rel_sigma=self.config.match.width_rel_sigma,
                )
                if meas is None or not self.in_room(meas.xy) or self._near_track(meas):
                    continue
                mono_k = self.config.match.mono_gate_sigmas
                if range_mismatch(a, ii, meas.xy) >= mono_k or range_mismatch(b, jj, meas.xy) >= mono_k:
                    continue  # a crossing of two other people's rays: the feet are elsewhere
                support, against = self._third_views(meas, views, (a_id, b_id))
                if against >= self.config.match.ghost_veto_views and not agreement_ok(meas):
                    continue
                links = {a_id: left[a_id][ii], b_id: left[b_id][jj]}
                hyps.append((support, meas.predicted_error_m, meas, links))
        hyps.sort(key=lambda h: (-h[0], h[1]))
        taken: set[tuple[str, int]] = set()
        accepted: list[FloatArray] = []
        born = 0
        for _, _, meas, links in hyps:
            if any((s, i) in taken for s, i in links.items()):
                continue
            if any(float(np.hypot(*(meas.xy - p))) < 0.5 for p in accepted):
                continue
            taken.update(links.items())
            accepted.append(meas.xy)
            ids = {s: int(views[s].local_id[i]) for s, i in links.items()}
            self.tracker.spawn(_reindex(meas, links), t_ns, ids)
            born += 1
        return born

    def _near_track(self, meas: Measurement) -> bool:
        if self._gates is None:
            tracks = self.tracker.tracks
            self._gates = (
                np.array([tr.x[:2] for tr in tracks]).reshape(-1, 2),
                np.array([self.tracker.position_gate_m(tr) for tr in tracks]),
            )
        xy, radius = self._gates
        if not radius.size:
            return False
        return bool(np.any(np.hypot(xy[:, 0] - meas.xy[0], xy[:, 1] - meas.xy[1]) < radius))

    def _third_views(self, meas: Measurement, views: dict[str, ViewBlobs], pair: tuple[str, str]) -> tuple[int, int]:
        """Cameras outside the pair that do / do not see a blob toward the hypothesis."""
        k = self.config.match.bearing_gate_sigmas
        support = against = 0
        for sid, v in views.items():
            if sid in pair:
                continue
            rel = meas.xy - v.origin_xy
            dist = float(np.hypot(*rel))
            if dist > self.params.max_range_m or dist < 0.3:
                continue
            pred = math.atan2(rel[1], rel[0])
            if not v.sees(pred):
                continue
            gate = k * v.sigma_rad + 0.3 / dist
            if v.n and float(np.min(np.abs(wrap(v.bearing_rad - pred)) - 0.5 * v.width_rad)) < gate:
                support += 1
            else:
                against += 1
        return support, against


def _reindex(meas: Measurement, links: dict[str, int]) -> Measurement:
    """Blob indices of a subset view back to the full view's."""
    return Measurement(
        xy=meas.xy,
        cov=meas.cov,
        height_m=meas.height_m,
        method=meas.method,
        sensors=meas.sensors,
        predicted_error_m=meas.predicted_error_m,
        blobs=tuple((s, links[s]) for s, _ in meas.blobs),
    )
