"""How often each multi-view detector finds a person who is there, learnt from the tracks.

Some views' boxes are not their camera's own detections but one floor detection per person drawn into every view
whose picture holds them (:attr:`~resource_manager.views.blobs.Views.shared_detector`: a multi-view detector's
output, or an annotation made on the floor). Such views find or miss a person together, whether or not nearer people
cover them: a miss is one event, however many views share it, and its probability is the detector's own, which
differs by detector (an annotator misses almost nobody; a detector, some). :class:`SharedRecall` learns it per
detector from the tracks the tracker is surest of (published, placed and more likely there than not), from a prior
of ``p_detect`` worth :data:`PRIOR_S` of one track's evidence.

A tick at which the detector found nobody of such a track counts only once the person is shown to have been there:
when some view detects the track again, or, if those misses ended the track, when a new person appears where it
would be within ``evidence_time_s`` (:meth:`SharedRecall.found`). Someone who walked out of the cameras' sight is
no miss of the detector.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from common.arrays import BoolArray, FloatArray, IntArray
from resource_manager.track.life import match_returns
from resource_manager.track.model import TrackModel
from resource_manager.track.motion import MotionModel, predict

__all__ = ["MAX_RECALL", "MEMORY_S", "PRIOR_S", "SharedRecall", "detector_misses"]

PRIOR_S = 10.0
"""Weight (s of one track's evidence) of the prior: the recall moves off ``p_detect`` once the tracks have shown
it for about this long."""
MEMORY_S = 600.0
"""Evidence this old (s) has faded to 1/e: a detector can be changed."""
MAX_RECALL = 0.999
"""No detector is taken as surer than this: a miss always says a little."""

Tally = tuple[float, float]
"""(s of ticks counted, s of them at which the detector found the person)."""


def detector_misses(ln_miss: FloatArray, got: BoolArray, once: FloatArray) -> FloatArray:
    """(g, n) the misses of one shared detector's ``g`` views of ``n`` people as that one detector's: ``ln_miss``
    (g, n) each view's own ln(1 - P_D) of each person where it did not find them (0 where it should not see them),
    ``got`` (g, n) where a view found them. Where some view found a person, the detector found them, and its other
    views' misses say nothing (0: its box there went to someone else, or lay outside the gate); where none did, the
    detector missed them once: ``once`` (n,) on the first view that should see them, 0 on the others."""
    missed = (ln_miss < 0.0) & ~got
    cols = np.flatnonzero(~got.any(axis=0) & missed.any(axis=0))
    out = np.zeros(ln_miss.shape)
    out[np.argmax(missed, axis=0)[cols], cols] = once[cols]
    return out


class SharedRecall:
    """Each shared detector's recall: the probability that it finds a person who is in some of its views' pictures."""

    def __init__(self, model: TrackModel) -> None:
        self.model = model
        self._tally: dict[str, Tally] = {}
        self._pending: dict[tuple[int, str], float] = {}
        """(track serial, detector) -> s of ticks since the detector last found that track's person."""
        self._gone: list[tuple[int, FloatArray, FloatArray, dict[str, float]]] = []
        """Tracks that ended on such misses: (instant, state (4,), covariance (4, 4), detector -> their pending s)."""

    def recall(self, name: str) -> float:
        """Detector ``name``'s recall (the prior ``p_detect`` before any evidence)."""
        n, found = self._tally.get(name, (0.0, 0.0))
        r = (found + PRIOR_S * self.model.p_detect) / (n + PRIOR_S)
        return min(r, MAX_RECALL)

    def learnt(self) -> dict[str, float]:
        """Each multi-view detector seen so far, by name: its recall now."""
        return {name: self.recall(name) for name in sorted(self._tally)}

    # -- learning -------------------------------------------------------------------------------------
    def learn(
        self,
        groups: Mapping[str, IntArray],
        sees: BoolArray,
        got: BoolArray,
        *,
        sure: BoolArray,
        serials: list[int],
        dt_s: float,
    ) -> None:
        """One tick of ``dt_s``: ``groups`` each multi-view detector's view rows
        (:attr:`~resource_manager.views.blobs.Views.shared_groups`), ``sees`` (s, n) which views should see each track,
        ``got`` (s, n) which detected it, ``sure`` (n,) which tracks surely are someone (before this tick's evidence),
        ``serials`` their serials."""
        if dt_s <= 0.0 or not groups:
            return
        fade = math.exp(-dt_s / MEMORY_S)
        self._tally = {k: (n * fade, f * fade) for k, (n, f) in self._tally.items()}
        there: BoolArray = np.asarray(got.any(axis=0), dtype=bool)
        pending: dict[tuple[int, str], float] = {}
        for name, rows in groups.items():
            looked: BoolArray = np.asarray(sees[rows].any(axis=0), dtype=bool)
            found: BoolArray = np.asarray(got[rows].any(axis=0), dtype=bool)
            n, f = self._tally.get(name, (0.0, 0.0))
            for i, serial in enumerate(serials):
                key = (serial, name)
                if not looked[i] or not (sure[i] or key in self._pending):
                    continue  # a run of misses counts from a track that surely was someone
                missed = self._pending.get(key, 0.0)
                if found[i]:
                    n, f = n + missed + dt_s, f + dt_s
                elif there[i]:  # another detector shows the person there: this one missed them
                    n += missed + dt_s
                else:
                    pending[key] = missed + dt_s
            self._tally[name] = (n, f)
        self._pending = pending

    def ended(self, serial: int, x: FloatArray, p: FloatArray, t_ns: int) -> None:
        """Track ``serial`` ended at ``t_ns`` for want of detections, in state ``x`` (4,), ``p`` (4, 4): its pending
        misses wait for :meth:`found`."""
        mine = {name: s for (k, name), s in self._pending.items() if k == serial}
        for name in mine:
            del self._pending[(serial, name)]
        self._forget_gone(t_ns)
        if mine:
            self._gone.append((t_ns, x.copy(), p.copy(), mine))

    def _forget_gone(self, t_ns: int) -> None:
        """Forget the tracks that ended longer than ``evidence_time_s`` before ``t_ns``: nobody new was found there."""
        horizon = t_ns - int(self.model.evidence_time_s * 1e9)
        self._gone = [g for g in self._gone if g[0] >= horizon]

    def found(self, xy: FloatArray, cov: FloatArray, t_ns: int, motion: MotionModel) -> None:
        """New people at ``xy`` (h, 2) ± ``cov`` (h, 2, 2) at ``t_ns``: one where a track that ended within
        ``evidence_time_s`` (:meth:`ended`) would be now shows that track's last ticks were misses of someone there."""
        self._forget_gone(t_ns)
        if not self._gone or not len(xy):
            return
        pred = [predict(x, p, (t_ns - t0) / 1e9, motion) for t0, x, p, _ in self._gone]
        pairs = match_returns(
            np.asarray(xy, dtype=np.float64).reshape(-1, 2),
            np.asarray(cov, dtype=np.float64).reshape(-1, 2, 2),
            np.array([x[:2] for x, _ in pred]),
            np.array([p[:2, :2] for _, p in pred]),
        )
        for _, k in pairs:
            for name, missed in self._gone[k][3].items():
                n, f = self._tally.get(name, (0.0, 0.0))
                self._tally[name] = (n + missed, f)
        taken = {k for _, k in pairs}
        self._gone = [g for k, g in enumerate(self._gone) if k not in taken]
