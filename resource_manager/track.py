"""Tracking on the floor: a constant-velocity Kalman filter per person and the track life cycle.

State x = (x, y, vx, vy) in metres and m/s; white-acceleration process noise
(σ_a, ``accel_sigma_mps2``); measurements are floor positions with the
covariance of :mod:`resource_manager.localize`. A measurement is associated to
a track only inside a Mahalanobis gate (or within ``gate_min_m``).

Life cycle: a new person starts *tentative*; ``birth_hits`` measurements within
``birth_window`` ticks confirm it and give it an id ``{manager_id}-{n}``
(``n`` from a persisted counter, so ids never repeat, across managers and
restarts); a tentative track that cannot reach that dies quietly. A confirmed
track missing a measurement is *coasting* and dies after ``max_misses``
consecutive misses.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from common.schema import Method, TrackState
from resource_manager.localize import Measurement
from resource_manager.looks import mean_similarity
from resource_manager.pairs import PairCandidate

__all__ = ["TrackParams", "TrackRecord", "Tracker"]

FloatArray = npt.NDArray[np.float64]

_H = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]])


@dataclass(frozen=True, slots=True)
class TrackParams:
    accel_sigma_mps2: float = 3.0
    gate_chi2: float = 13.8
    gate_min_m: float = 0.3
    min_meas_sigma_m: float = 0.03
    birth_hits: int = 3
    birth_window: int = 5
    max_misses: int = 15
    init_speed_sigma_mps: float = 1.0
    height_alpha: float = 0.2
    max_speed_mps: float = 3.0
    """Velocity estimates are clamped to this (people walk; a jump between two people is not a speed)."""
    max_gate_m: float = math.inf
    """However uncertain a coasting track is, a fix further than this from its prediction is not its own."""
    coast_damping_s: float = math.inf
    """Time constant of the velocity decay while a track coasts (people stop and turn; a constant-velocity
    prediction of a lost person walks off through the walls)."""
    relink_s: float = 0.0
    """A confirmed track lost for ``max_misses`` ticks is held (unpublished) this long: a new track confirmed
    near where it was lost takes its id instead of a new one (0: off, a lost track ends at once)."""
    relink_m: float = 1.0
    """...when it is confirmed within this distance (plus 0.5 m per second lost) of the lost track's place."""
    same_look_min: float = 0.6
    """Two tracks whose colour looks (mean Bhattacharyya coefficient over the views both have) are below this
    are two people: a lost track does not lend its id to the other, and two confirmed tracks side by side are not
    pruned as one person's duplicates (0: looks are not compared)."""
    sure_look_min: float = 0.9
    """A lost track whose look matches a newly confirmed one this well lends it its id from twice ``relink_m``
    plus 1 m per second lost (a walker's reach) instead of ``relink_m`` plus 0.5 m/s (0: off)."""


@dataclass(slots=True, eq=False)
class TrackRecord:
    """One track's filter and bookkeeping (mutable, owned by the Tracker)."""

    serial: int
    x: FloatArray
    p: FloatArray
    t_ns: int
    born_ns: int
    track_id: str = ""
    height_m: float = 0.0
    state: TrackState = "tentative"
    hits: int = 1
    misses: int = 0
    window: deque[bool] = field(default_factory=deque)
    method: Method = "predicted"
    sensors: tuple[str, ...] = ()
    predicted_error_m: float = 0.0
    links: dict[str, int] = field(default_factory=dict)
    """sensor id -> the node's local blob id last associated with this track."""
    looks: dict[str, FloatArray] = field(default_factory=dict)
    """sensor id -> running mean of the square-rooted colour histograms of this track's blobs in that view
    (appearance per view: the same shirt looks different from another side or under another light)."""
    fixed_ns: int = 0
    """Fusion instant of the last stereo (pair or least-squares) fix; 0: none yet (see ``match.group_coast_s``)."""
    pair_cache: tuple[float, float, frozenset[str], list[PairCandidate]] | None = None
    """(x, y, cameras, ranked pairs) of the last pair ranking (re-ranked when the track moved or views changed)."""

    @property
    def xy(self) -> FloatArray:
        return self.x[:2]

    @property
    def confirmed(self) -> bool:
        return self.state != "tentative"


class Tracker:
    """All tracks of one manager.

    Args:
        params: filter and life-cycle settings.
        new_id: returns the next unique track id (called once per confirmed track).
    """

    def __init__(self, params: TrackParams, new_id: Callable[[], str]) -> None:
        self.params = params
        self.new_id = new_id
        self.tracks: list[TrackRecord] = []
        self.lost: list[TrackRecord] = []
        """Confirmed tracks lost for ``max_misses`` ticks, held ``relink_s`` for their id (oldest first)."""
        self._serial = 0
        self._now_ns = 0

    def predict(self, t_ns: int) -> None:
        """Move every track to the fusion instant ``t_ns`` (never backwards)."""
        q = self.params.accel_sigma_mps2**2
        self._now_ns = max(self._now_ns, t_ns)
        for tr in self.tracks:
            dt = (t_ns - tr.t_ns) / 1e9
            if dt <= 0:
                continue
            f = np.eye(4)
            f[0, 2] = f[1, 3] = dt
            g = np.array([[dt * dt / 2, 0.0], [0.0, dt * dt / 2], [dt, 0.0], [0.0, dt]])
            tr.x = f @ tr.x
            tr.p = f @ tr.p @ f.T + q * (g @ g.T)
            tr.t_ns = t_ns
            if tr.misses > 0 and math.isfinite(self.params.coast_damping_s):
                tr.x[2:] *= math.exp(-dt / self.params.coast_damping_s)

    def innovation(self, tr: TrackRecord, m: Measurement) -> tuple[FloatArray, FloatArray]:
        r = m.cov + self.params.min_meas_sigma_m**2 * np.eye(2)
        nu = m.xy - tr.x[:2]
        s = _H @ tr.p @ _H.T + r
        return nu, s

    def gate_distance(self, tr: TrackRecord, m: Measurement) -> float:
        """Mahalanobis distance² of a measurement to a track, or inf outside the gate.

        The 2x2 innovation covariance S = P_xy + R is inverted in closed form (plain floats: this is asked for
        every candidate fix of every track on every tick).
        """
        r = self.params.min_meas_sigma_m**2
        p, c = tr.p, m.cov
        sxx = float(p[0, 0] + c[0, 0]) + r
        sxy = float(p[0, 1] + c[0, 1])
        syy = float(p[1, 1] + c[1, 1]) + r
        nx, ny = float(m.xy[0] - tr.x[0]), float(m.xy[1] - tr.x[1])
        det = sxx * syy - sxy * sxy
        d2 = (syy * nx * nx - 2.0 * sxy * nx * ny + sxx * ny * ny) / det if det > 0 else math.inf
        dist = math.hypot(nx, ny)
        if dist <= self.params.gate_min_m or (d2 <= self.params.gate_chi2 and dist <= self.params.max_gate_m):
            return d2
        return math.inf

    def position_gate_m(self, tr: TrackRecord) -> float:
        """A radius that contains the gate (for cheap spatial pre-filtering)."""
        ev = float(np.max(np.linalg.eigvalsh(tr.p[:2, :2])))
        radius = min(math.sqrt(self.params.gate_chi2 * (ev + 0.01)), self.params.max_gate_m)
        return max(self.params.gate_min_m, radius)

    def update(self, tr: TrackRecord, m: Measurement, links: dict[str, int]) -> None:
        """Kalman update with a measurement; counts a hit and may confirm the track.

        A measurement outside the motion gate (taken because the nodes' 2D tracks say it is the same person,
        ``match.link_gate_m``) contradicts the constant-velocity model: it moves the position as usual but not
        the velocity, which keeps its prediction with the uncertainty of a new track. The Kalman gain would turn
        the whole jump into metres per second (one camera's blob merged with a ghost for a tick: 2.2 m/s in a
        paper1 replay), and the track would walk off on it while the next fixes are missing.
        """
        jump = not math.isfinite(self.gate_distance(tr, m))
        velocity = tr.x[2:].copy()
        nu, s = self.innovation(tr, m)
        k = tr.p @ _H.T @ np.linalg.inv(s)
        tr.x = tr.x + k @ nu
        tr.p = (np.eye(4) - k @ _H) @ tr.p
        tr.p = 0.5 * (tr.p + tr.p.T)
        if jump:
            tr.x[2:] = velocity
            tr.p[2:, :2] = tr.p[:2, 2:] = 0.0
            tr.p[2:, 2:] = self.params.init_speed_sigma_mps**2 * np.eye(2)
        self._clamp_speed(tr)
        if m.height_m > 0:
            a = self.params.height_alpha if tr.height_m > 0 else 1.0
            tr.height_m += a * (m.height_m - tr.height_m)
        tr.method = m.method
        tr.sensors = m.sensors
        tr.predicted_error_m = m.predicted_error_m
        tr.links.update(links)
        tr.hits += 1
        tr.misses = 0
        self._window(tr, True)
        if tr.state == "tentative":
            if sum(tr.window) >= self.params.birth_hits:
                tr.state = "confirmed"
                tr.track_id = self._relink(tr) or self.new_id()
        else:
            tr.state = "confirmed"

    def _clamp_speed(self, tr: TrackRecord) -> None:
        speed = math.hypot(float(tr.x[2]), float(tr.x[3]))
        if speed > self.params.max_speed_mps:
            tr.x[2:] *= self.params.max_speed_mps / speed

    def bearing_update(self, tr: TrackRecord, origin_xy: FloatArray, bearing_rad: float, sigma_rad: float) -> bool:
        """Extended Kalman update with one camera's bearing (a single ray); False if outside the gate."""
        dx, dy = float(tr.x[0] - origin_xy[0]), float(tr.x[1] - origin_xy[1])
        r2 = dx * dx + dy * dy
        if r2 < 0.09:
            return False
        h = np.array([[-dy / r2, dx / r2, 0.0, 0.0]])
        nu = math.remainder(bearing_rad - math.atan2(dy, dx), 2 * math.pi)
        s = float((h @ tr.p @ h.T)[0, 0]) + sigma_rad**2
        if nu * nu / s > self.params.gate_chi2:
            return False
        k = (tr.p @ h.T) / s
        tr.x = tr.x + (k * nu).ravel()
        tr.p = (np.eye(4) - k @ h) @ tr.p
        tr.p = 0.5 * (tr.p + tr.p.T)
        self._clamp_speed(tr)
        return True

    def hold(self, tr: TrackRecord) -> None:
        """No fix, but the track is known to be hidden (in a merged group): it coasts without counting a miss."""
        tr.method = "predicted"
        tr.sensors = ()
        if tr.state == "confirmed":
            tr.state = "coasting"

    def miss(self, tr: TrackRecord) -> None:
        tr.misses += 1
        tr.method = "predicted"
        tr.sensors = ()
        self._window(tr, False)
        if tr.state == "confirmed":
            tr.state = "coasting"

    def _window(self, tr: TrackRecord, hit: bool) -> None:
        tr.window.append(hit)
        while len(tr.window) > self.params.birth_window:
            tr.window.popleft()

    def spawn(self, m: Measurement, t_ns: int, links: dict[str, int]) -> TrackRecord:
        """Start a tentative track at a measurement."""
        self._serial += 1
        p = self._initial_cov(m)
        tr = TrackRecord(
            serial=self._serial,
            x=np.array([m.xy[0], m.xy[1], 0.0, 0.0]),
            p=p,
            t_ns=t_ns,
            born_ns=t_ns,
            fixed_ns=t_ns,
            height_m=m.height_m,
            method=m.method,
            sensors=m.sensors,
            predicted_error_m=m.predicted_error_m,
            links=dict(links),
        )
        tr.window.append(True)
        if self.params.birth_hits <= 1:
            tr.state = "confirmed"
            tr.track_id = self.new_id()
        self.tracks.append(tr)
        return tr

    def _initial_cov(self, m: Measurement) -> FloatArray:
        """State covariance of a track started at a measurement: its position error, an unknown walking speed."""
        p = np.zeros((4, 4))
        p[:2, :2] = m.cov + self.params.min_meas_sigma_m**2 * np.eye(2)
        p[2, 2] = p[3, 3] = self.params.init_speed_sigma_mps**2
        return p

    def _relink(self, tr: TrackRecord) -> str:
        """The id of the lost track nearest a newly confirmed one, if it is near enough to be that person."""
        p = self.params
        best: TrackRecord | None = None
        best_d = math.inf
        for old in self.lost:
            dt_s = max(0.0, (tr.t_ns - old.t_ns) / 1e9)
            d = math.hypot(float(tr.x[0] - old.x[0]), float(tr.x[1] - old.x[1]))
            sim = look_similarity(tr, old)
            sure = p.sure_look_min > 0 and (sim or 0.0) >= p.sure_look_min
            reach_m = 2.0 * p.relink_m + 1.0 * dt_s if sure else p.relink_m + 0.5 * dt_s
            if dt_s > p.relink_s or d > reach_m:
                continue
            if tr.height_m > 0 and old.height_m > 0 and abs(tr.height_m - old.height_m) > 0.15:
                continue  # a head this much taller or shorter is someone else
            if self._looks_apart(sim):
                continue  # another shirt
            if d < best_d:
                best, best_d = old, d
        if best is None:
            return ""
        self.lost.remove(best)
        tr.born_ns = best.born_ns
        return best.track_id

    def _differ(self, a: TrackRecord, b: TrackRecord) -> bool:
        """True if two tracks' colour looks say they are two people."""
        return self.params.same_look_min > 0 and self._looks_apart(look_similarity(a, b))

    def _looks_apart(self, sim: float | None) -> bool:
        """True if a similarity of two tracks' looks (None: nothing to compare) says they are two people."""
        return self.params.same_look_min > 0 and sim is not None and sim < self.params.same_look_min

    def prune(self) -> list[TrackRecord]:
        """Remove dead tracks; return the confirmed ones that ended (their ids are retired)."""
        keep: list[TrackRecord] = []
        ended: list[TrackRecord] = []
        p = self.params
        for tr in self.tracks:
            if tr.state == "tentative":
                needed = p.birth_hits - sum(tr.window)
                if needed > p.birth_window - len(tr.window) or tr.misses >= 2:
                    continue
                keep.append(tr)
            elif tr.misses > p.max_misses or (
                tr.misses >= 3 and any(o is not tr and o.confirmed and _shared_links(o, tr) >= 2 for o in self.tracks)
            ):
                # Lost, or a coasting copy of a track that holds its blobs: held for its id a while (see _relink).
                (self.lost if p.relink_s > 0 else ended).append(tr)
            else:
                keep.append(tr)
        # Two tracks on one person: the younger (or tentative) one goes.
        keep.sort(key=lambda t: (not t.confirmed, t.born_ns, t.serial))
        final: list[TrackRecord] = []
        kept_xy: list[tuple[float, float]] = []  # plain floats: this is O(tracks^2) every tick
        for tr in keep:
            tx, ty = float(tr.x[0]), float(tr.x[1])
            dup = next(
                (
                    o
                    for o, (ox, oy) in zip(final, kept_xy, strict=True)
                    if math.hypot(ox - tx, oy - ty) < 0.3 and (o.confirmed or not tr.confirmed)
                ),
                None,
            )
            if dup is not None and tr.confirmed and self._differ(dup, tr):
                dup = None  # two people side by side (one track pulled onto the other's fixes): their shirts differ
            if dup is not None and (not tr.confirmed or tr.misses > 0 or _shared_links(dup, tr) >= 2):
                if tr.confirmed:
                    (self.lost if p.relink_s > 0 else ended).append(tr)
                continue
            final.append(tr)
            kept_xy.append((tx, ty))
        self.tracks = final
        held: list[TrackRecord] = []
        for tr in self.lost:
            (ended if (self._now_ns - tr.t_ns) / 1e9 > p.relink_s else held).append(tr)
        self.lost = held
        return ended


def _shared_links(a: TrackRecord, b: TrackRecord) -> int:
    """How many cameras attribute the same node-side blob to both tracks (two tracks on one person)."""
    return sum(1 for sid, lid in a.links.items() if b.links.get(sid) == lid)


def look_similarity(a: TrackRecord, b: TrackRecord) -> float | None:
    """Mean Bhattacharyya coefficient of two tracks' per-view colour looks over the views both have.

    Returns:
        In [0, 1] (1: the same colours), or None when the tracks have no look in a common view.
    """
    return mean_similarity((a.looks[sid], look) for sid, look in b.looks.items() if sid in a.looks)
