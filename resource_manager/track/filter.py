"""Every track's state in one place: where each person is, how sure the tracker is of them, how tall they are.

:class:`TrackFilter` owns, for all tracks at once (row ``i`` is track ``i`` of the tracker), the floor state
``(x, y, vx, vy)`` with its covariance, the head-top height with its variance and the existence log-odds, and is
the only code that changes them:

* :meth:`TrackFilter.predict` moves every track to the fusion instant (the motion model of :mod:`.motion`);
* :meth:`TrackFilter.fuse` updates tracks with the views assigned to them (the iterated EKF of :mod:`.fuse`),
  :meth:`TrackFilter.fix` with one pair's fix (the paper mode), :meth:`TrackFilter.fuse_heights` their heights;
* :meth:`TrackFilter.existence` moves each track's existence with every view's evidence (detected, or missed
  where the view should have seen it), each tempered so a view's frames within ``evidence_time_s`` count once,
  and held below a cap that says where the person could have left (:mod:`.life`);
* :meth:`TrackFilter.add` and :meth:`TrackFilter.keep` start and end rows.

Arrays in, arrays out: every operation works on all the tracks it is given at once.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from common.arrays import BoolArray, FloatArray, IntArray
from resource_manager.track.fuse import Slots, fuse, fuse_heights, observations
from resource_manager.track.motion import MotionModel, predict_many, update_without_each
from resource_manager.track.observe import TrackTable
from resource_manager.views.blobs import Views

__all__ = ["TrackFilter", "worst_sigma"]


def worst_sigma(cov: FloatArray) -> FloatArray:
    """(n,) the 1-sigma spread in its worst direction of each (n, 2, 2) floor covariance (its larger eigenvalue's
    square root, in closed form)."""
    a, b, c = cov[:, 0, 0], cov[:, 0, 1], cov[:, 1, 1]
    return np.asarray(np.sqrt(np.maximum(0.5 * (a + c) + np.hypot(0.5 * (a - c), b), 0.0)), dtype=np.float64)


class TrackFilter:
    """The state of every track (see the module docstring).

    Args:
        motion: how people move.
        height_change_mps: how fast a head-top height may change.
        height_outlier: (probability, scale) of a head-top height off by several sigmas (see
            :func:`.fuse.fuse_heights`); None: every height is trusted.
    """

    def __init__(
        self, motion: MotionModel, height_change_mps: float, height_outlier: tuple[float, float] | None = None
    ) -> None:
        self.motion = motion
        self.height_change_mps = height_change_mps
        self.height_outlier = height_outlier
        self.x: FloatArray = np.zeros((0, 4))
        """(n, 4) x, y (m) and vx, vy (m/s) on the floor."""
        self.p: FloatArray = np.zeros((0, 4, 4))
        """(n, 4, 4) covariances of ``x``."""
        self.height: FloatArray = np.zeros(0)
        """(n,) head-top heights above the floor (m)."""
        self.height_var: FloatArray = np.zeros(0)
        self.logodds: FloatArray = np.zeros(0)
        """(n,) existence: ln(p / (1 - p)) of the probability that the track is a person."""
        self.t_ns: IntArray = np.zeros(0, dtype=np.int64)
        """(n,) instant of each row's state."""
        self.seen_x: FloatArray = np.zeros((0, 4))
        """(n, 4) each track's state when a view last detected it (:meth:`mark_seen`)..."""
        self.seen_p: FloatArray = np.zeros((0, 4, 4))
        """(n, 4, 4) ...and its covariance: where a lost person was last known to be."""

    @property
    def n(self) -> int:
        return int(self.x.shape[0])

    # -- rows ------------------------------------------------------------------------------------------
    def add(
        self,
        x: FloatArray,
        p: FloatArray,
        *,
        height: FloatArray,
        height_var: FloatArray,
        logodds: FloatArray,
        t_ns: int,
    ) -> None:
        """Append rows: states ``x`` (k, 4) with covariances ``p`` (k, 4, 4), heights, existence, at ``t_ns``."""
        k = len(x)
        self.x = np.concatenate([self.x, np.asarray(x, dtype=np.float64).reshape(k, 4)])
        self.p = np.concatenate([self.p, np.asarray(p, dtype=np.float64).reshape(k, 4, 4)])
        self.height = np.concatenate([self.height, np.asarray(height, dtype=np.float64).reshape(k)])
        self.height_var = np.concatenate([self.height_var, np.asarray(height_var, dtype=np.float64).reshape(k)])
        self.logodds = np.concatenate([self.logodds, np.asarray(logodds, dtype=np.float64).reshape(k)])
        self.t_ns = np.concatenate([self.t_ns, np.full(k, t_ns, dtype=np.int64)])
        self.seen_x = np.concatenate([self.seen_x, self.x[-k:] if k else np.zeros((0, 4))])
        self.seen_p = np.concatenate([self.seen_p, self.p[-k:] if k else np.zeros((0, 4, 4))])

    def keep(self, rows: IntArray) -> None:
        """Keep only ``rows``, in that order (the others end)."""
        rows = np.asarray(rows, dtype=np.int64)
        self.x, self.p = self.x[rows], self.p[rows]
        self.height, self.height_var = self.height[rows], self.height_var[rows]
        self.logodds, self.t_ns = self.logodds[rows], self.t_ns[rows]
        self.seen_x, self.seen_p = self.seen_x[rows], self.seen_p[rows]

    def mark_seen(self, rows: IntArray) -> None:
        """Remember the state of ``rows`` as where their people were last seen (a view detected them now)."""
        rows = np.asarray(rows, dtype=np.int64)
        self.seen_x[rows], self.seen_p[rows] = self.x[rows], self.p[rows]

    # -- reading ---------------------------------------------------------------------------------------
    def table(self, rows: IntArray | None = None) -> TrackTable:
        """The tracks (or ``rows``) as the arrays the views are scored against."""
        sel = slice(None) if rows is None else np.asarray(rows, dtype=np.int64)
        return TrackTable(self.x[sel, :2].copy(), self.p[sel, :2, :2].copy(), self.height[sel], self.height_var[sel])

    def position_sigma(self) -> FloatArray:
        """(n,) 1-sigma position error of each track in its worst direction."""
        return worst_sigma(self.p[:, :2, :2])

    def existence(self) -> FloatArray:
        """(n,) probability that each track is a person."""
        return np.asarray(1.0 / (1.0 + np.exp(-self.logodds)), dtype=np.float64)

    # -- prediction ------------------------------------------------------------------------------------
    def predict(self, t_ns: int) -> FloatArray:
        """Every track to the instant ``t_ns`` (all at once); returns each one's gap (s)."""
        gaps_s = (t_ns - self.t_ns) / 1e9
        if self.n:
            self.x, self.p = predict_many(self.x, self.p, gaps_s, self.motion)
            self.height_var = self.height_var + self.height_change_mps**2 * np.maximum(gaps_s, 0.0)
            self.t_ns = np.full(self.n, t_ns, dtype=np.int64)
        return np.asarray(gaps_s, dtype=np.float64)

    # -- updates ---------------------------------------------------------------------------------------
    def fuse(
        self, rows: IntArray, assigned: Sequence[Sequence[tuple[str, int]]], views: Views, **options: Any
    ) -> list[FloatArray]:
        """Update ``rows`` with the blobs ``assigned`` to each (sensor id, blob), by :func:`.fuse.fuse` and its
        ``options`` (``feet_cut`` (s, len(rows)): the chance that a view's box of each is cut above the feet,
        ``cut_reach_m`` how far such a box can read, ...); returns each one's weight of each of its blobs (low: an
        outlier)."""
        if not len(rows):
            return []
        rows = np.asarray(rows, dtype=np.int64)
        x, p, resp = self.fused(rows, assigned, views, **options)
        self.x[rows], self.p[rows] = x, p
        return [resp[k, : len(got)] for k, got in enumerate(assigned)]

    def fused(
        self, rows: IntArray, assigned: Sequence[Sequence[tuple[str, int]]], views: Views, **options: Any
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """What :meth:`fuse` would make of ``rows`` (a row may come more than once, with other blobs), without
        keeping it: (states (k, 4), covariances (k, 4, 4), the weight (k, w) of each one's blobs)."""
        return fuse(self.x[rows], self.p[rows], Slots.of(assigned, views), views, **options)

    def fused_without_each(
        self, rows: IntArray, slots: Slots, views: Views, *, outlier: tuple[float, float], **options: Any
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """What :meth:`fused` would make of ``rows`` with the blobs of their ``slots``, and of each without each of
        its blobs in turn (:func:`.motion.update_without_each` of :func:`.fuse.observations`), without keeping it:
        (x (k, 4), P (k, 4, 4); x (k, w, 4), P (k, w, 4, 4) without slot w)."""
        x, p = self.x[rows], self.p[rows]
        return update_without_each(x, p, observations(x, p, slots, views, outlier=outlier, **options), outlier)

    def fix(self, row: int, xy: FloatArray, cov: FloatArray) -> None:
        """Linear Kalman update of ``row`` with a floor position (the paper mode's pair fix)."""
        h = np.zeros((2, 4))
        h[0, 0] = h[1, 1] = 1.0
        x, p = self.x[row], self.p[row]
        s = h @ p @ h.T + cov
        k = np.linalg.solve(s, h @ p).T
        self.x[row] = x + k @ (xy - x[:2])
        p_new = (np.eye(4) - k @ h) @ p
        self.p[row] = 0.5 * (p_new + p_new.T)

    def fuse_heights(self, rows: IntArray, assigned: Sequence[Sequence[tuple[str, int]]], views: Views) -> None:
        """Fuse into ``rows`` the head-top heights their assigned blobs imply at their distances."""
        if not len(rows):
            return
        rows = np.asarray(rows, dtype=np.int64)
        self.height[rows], self.height_var[rows] = fuse_heights(
            self.x[rows, :2],
            self.height[rows],
            self.height_var[rows],
            Slots.of(assigned, views),
            views,
            outlier=self.height_outlier,
        )

    def existence_update(self, delta: FloatArray, weight: FloatArray, sees: BoolArray, cap: FloatArray) -> None:
        """Move every track's existence view after view: ``delta`` (s, n) each view's ln likelihood ratio (detected
        or missed), ``weight`` (s,) its tempering, only where ``sees`` (s, n); held below ``cap`` (n,) log-odds."""
        lo = self.logodds.copy()
        for row in range(delta.shape[0]):
            moved = np.minimum(lo + weight[row] * delta[row], cap)
            lo = np.where(sees[row], moved, lo)
        self.logodds = lo

    def set_logodds(self, rows: IntArray, logodds: FloatArray) -> None:
        self.logodds[np.asarray(rows, dtype=np.int64)] = logodds
