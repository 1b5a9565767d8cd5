"""A standby's tracks named after the leader's: the ids a warm standby publishes under when it takes over.

A standby manager fuses the same frames as its zone's leader (resource_manager/serve/election.py), so it follows the
same people, but its tracks were born under its own ids (``{manager_id}-{n}``: no two managers ever mint the same
id). While it stands by it also hears the leader's TrackSets, and names each of its confirmed tracks after the
leader's track of the same person: the nearest one, at the standby's instant (the leader's position carried there
by its velocity), one to one (Hungarian) and within ``gate_m``. When the leader goes, the standby publishes the
people under the ids the agents already know.

The leader's tracks also carry what it knows of who is who: two of them are two people. Two of the standby's
tracks that follow two different tracks of the leader are held apart as if a view had shown them so (a standby
that came up while two people stood together has never seen them apart, and would take them for one person
followed twice; the leader, watching longer, has).

A track still tentative here that follows one of the leader's is confirmed under that id (the standby has
seen the person for less time than the leader, which confirmed them already; a takeover in that moment keeps
the id).

Pure: the tracker's snapshots and the leader's tracks in, the renames out; the tracker applies them
(:meth:`resource_manager.track.tracker.Tracker.adopt`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.optimize import linear_sum_assignment

from common.arrays import FloatArray, IntArray
from common.schema import Track
from resource_manager.track.tracker import TrackSnapshot

__all__ = ["GATE_M", "adopt_ids", "carried", "follows", "match_tracks"]

GATE_M = 0.75
"""Farthest a standby's track may be from the leader's to be named after it (a person's width and a half: the two
managers' estimates of one person differ by their alignment instants, centimetres)."""


MAX_CARRY_S = 1.0
"""Another manager's track is carried by its velocity over at most this long: a stale set is not extrapolated far."""


def carried(theirs: Sequence[Track], t_ns: IntArray) -> FloatArray:
    """(n, m, 2) each of the ``m`` tracks ``theirs`` carried by its velocity to each of the ``n`` instants ``t_ns``."""
    b = np.array([[t.x_m, t.y_m] for t in theirs], dtype=np.float64).reshape(-1, 2)
    v = np.array([[t.vx_mps, t.vy_mps] for t in theirs], dtype=np.float64).reshape(-1, 2)
    dt = (np.asarray(t_ns, dtype=np.float64)[:, None] - np.array([t.stamp_ns for t in theirs])) / 1e9
    dt = np.clip(dt, -MAX_CARRY_S, MAX_CARRY_S)
    return np.asarray(b[None, :, :] + v[None, :, :] * dt[:, :, None], dtype=np.float64)


def match_tracks(xy: FloatArray, t_ns: IntArray, theirs: Sequence[Track], gate_m: float = GATE_M) -> dict[int, int]:
    """Index of each of ``n`` positions ``xy`` (n, 2) at instants ``t_ns`` (n,) -> the index of the track of
    ``theirs`` of the same person: the nearest, each of theirs carried to the instant by its velocity
    (:func:`carried`), one to one (Hungarian) and within ``gate_m``."""
    if not len(xy) or not theirs:
        return {}
    a = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    dist = np.linalg.norm(a[:, None, :] - carried(theirs, t_ns), axis=2)
    cost = np.where(dist <= gate_m, dist, 1e6)
    rows, cols = linear_sum_assignment(cost)
    return {r: c for r, c in zip(rows.tolist(), cols.tolist(), strict=True) if dist[r, c] <= gate_m}


def follows(mine: Sequence[TrackSnapshot], theirs: Sequence[Track], gate_m: float = GATE_M) -> dict[int, str]:
    """Serial of each of ``mine`` -> the id of the other manager's track of the same person
    (:func:`match_tracks`): the confirmed ones first, then the tentative ones among the tracks left; empty if the
    other set names one id twice."""
    if len({t.track_id for t in theirs}) != len(theirs):
        return {}
    out: dict[int, str] = {}
    left = list(theirs)
    for own in ([tr for tr in mine if tr.track_id], [tr for tr in mine if not tr.confirmed]):
        if not own or not left:
            continue
        xy = np.array([tr.xy for tr in own], dtype=np.float64)
        pairs = match_tracks(xy, np.array([tr.t_ns for tr in own], dtype=np.int64), left, gate_m)
        out.update({own[r].serial: left[c].track_id for r, c in pairs.items()})
        used = set(pairs.values())
        left = [t for c, t in enumerate(left) if c not in used]
    return out


def adopt_ids(
    mine: Sequence[TrackSnapshot],
    followed: dict[int, str],
    taken: frozenset[str] = frozenset(),
) -> dict[int, str]:
    """Serial of each of ``mine`` -> the id of the other manager's track it follows (``followed``, from
    :func:`follows`), where that differs from its own and no other of ``mine`` keeps it (two of mine may swap ids),
    nor is it one of ``taken`` (ids this manager publishes for tracks not among ``mine``)."""
    own = {tr.serial: tr.track_id for tr in mine if tr.track_id}
    wanted = {serial: want for serial, want in followed.items() if serial in own and own[serial] != want}
    # An id stays with a track that keeps its own; one that another of mine gives up this time may be taken (a swap).
    kept = {tid for serial, tid in own.items() if serial not in wanted} | taken
    return {serial: want for serial, want in wanted.items() if want not in kept}
