"""Step 1 of a tick: which blob of each camera supports which predicted track.

Per camera with a known pose, predicted tracks and blobs are assigned one to one (Hungarian) on the bearing gate
(``bearing_gate_sigmas``: bearing error plus the track's position uncertainty seen from that camera, plus
:data:`SUPPORT_HALF_M` of lateral slack) and, for perspective cameras that see the feet, the floor distance
(:mod:`.mono`); the blob the node tracked for the track last tick (same ``local_id``) gets a bonus, not a free
pass (2D ids swap in crowds), and with ``look_weight`` a blob in another track's colours costs more
(:mod:`.looks`). A track left without a blob whose nearest blob is another track's *shares* it (hidden behind
that person, or walking in one merged blob with them: :mod:`.group`).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
from scipy.optimize import linear_sum_assignment

from resource_manager.looks import bhattacharyya
from resource_manager.match import ViewBlobs
from resource_manager.track import TrackRecord
from resource_manager.views import wrap

__all__ = ["LINK_BONUS", "SUPPORT_HALF_M", "assign_support"]

FloatArray = npt.NDArray[np.float64]
_FORBID = 1e6
SUPPORT_HALF_M = 0.2
"""Lateral slack (m) of the support gate around a track's predicted bearing: a head is within about this of the
body's centre line. Under half the ~0.5 m between two people walking side by side, so one track's gate does not
reach across to the neighbour's blob (0.25: demo recordings, seed 7, MOTA 0.913 mean of 5 vs 0.931 at 0.2)."""
LINK_BONUS = 0.5
"""Cost bonus (in squared gate units) of the blob with the node-side id a track had last tick."""


def assign_support(
    views: dict[str, ViewBlobs],
    tracks: list[TrackRecord],
    *,
    gate_sigmas: float,
    max_range_m: float,
    look_weight: float = 0.0,
) -> tuple[list[dict[str, int]], list[dict[str, int]]]:
    """For each track, sensor id -> index of its own supporting blob, and of blobs it shares.

    Per camera, tracks and blobs inside the gate (bearing, and the feet's floor distance where known) are
    assigned one to one; a track left without a blob whose nearest blob is another track's shares it.
    """
    out: list[dict[str, int]] = [{} for _ in tracks]
    shared: list[dict[str, int]] = [{} for _ in tracks]
    vs = [v for v in views.values() if v.n]
    if not tracks or not vs:
        return out, shared
    txy = np.array([tr.x[:2] for tr in tracks])
    tvar = np.array([max(tr.p[0, 0], tr.p[1, 1]) for tr in tracks])
    k = gate_sigmas
    links: dict[str, npt.NDArray[np.int64]] = {}
    for t, tr in enumerate(tracks):
        for sid, lid in tr.links.items():
            if sid not in links:
                links[sid] = np.full(len(tracks), -1, dtype=np.int64)
            links[sid][t] = lid
    # Gates of every (view, track) and normalised distances of every (blob, track) in one pass over all
    # views (per view: the same arithmetic on its rows); only the one-to-one assignment is per view.
    counts = [v.n for v in vs]
    of = np.repeat(np.arange(len(vs)), counts)
    rel = txy[None, :, :] - np.array([v.origin_xy for v in vs])[:, None, :]  # (views, tracks, 2)
    dist = np.maximum(np.hypot(rel[..., 0], rel[..., 1]), 0.3)
    pred = np.arctan2(rel[..., 1], rel[..., 0])
    sig2 = np.array([v.sigma_rad**2 for v in vs])[:, None]
    gate = k * np.sqrt(sig2 + tvar / dist**2) + SUPPORT_HALF_M / dist
    bearing = np.concatenate([v.bearing_rad for v in vs])
    norm = np.abs(wrap(bearing[:, None] - pred[of])) / gate[of]  # (blobs, tracks)
    if any(v.mono_range_m is not None and v.mono_sigma_m is not None for v in vs):
        # Floor distance from the feet (mono.py): along the ray too, within the same number of sigmas.
        known = [v.mono_range_m is not None and v.mono_sigma_m is not None for v in vs]
        pairs = list(zip(vs, known, strict=True))
        rng_m = np.concatenate([v.mono_range_m if ok else np.full(v.n, np.nan) for v, ok in pairs])
        sig_m = np.concatenate([v.mono_sigma_m if ok else np.full(v.n, np.nan) for v, ok in pairs])
        s_r = np.sqrt(sig_m[:, None] ** 2 + tvar[None, :])
        rn = np.abs(rng_m[:, None] - dist[of]) / (k * s_r)
        with_feet = np.repeat(np.array(known), counts)
        norm = np.where(with_feet[:, None], np.hypot(norm, np.nan_to_num(rn, nan=0.0)), norm)
    ok_all = (norm < 1.0) & ~(dist > max_range_m)[of]
    cost_all = np.where(ok_all, norm**2, _FORBID)
    stop = 0
    for v, n in zip(vs, counts, strict=True):
        sid = v.sensor_id
        sl = slice(stop, stop + n)
        stop += n
        ok = ok_all[sl]
        if not ok.any():
            continue
        # One blob per track and one track per blob, by least total normalised distance (Hungarian):
        # in a crowd, "each track takes its nearest blob" lets one track steal its neighbour's blob.
        # The blob the node kept tracking for it (same local id) gets a bonus, not a free pass: the
        # node's 2D ids swap between people who cross.
        cost = cost_all[sl]
        lids = links.get(sid)
        if lids is not None:
            cost = cost - LINK_BONUS * ((v.local_id[:, None] == lids[None, :]) & ok)
        if look_weight > 0 and v.hist_sqrt is not None:
            cost = cost + look_weight * _look_cost(sid, v.hist_sqrt, tracks, ok)
        rows_any = np.nonzero(ok.any(axis=1))[0]
        cols_any = np.nonzero(ok.any(axis=0))[0]
        sub = cost[np.ix_(rows_any, cols_any)]
        ri, ci = linear_sum_assignment(sub)
        good = sub[ri, ci] < _FORBID / 2
        blob_of = np.full(len(tracks), -1)
        blob_of[cols_any[ci[good]]] = rows_any[ri[good]]
        claimed = np.zeros(v.n, dtype=bool)
        claimed[blob_of[blob_of >= 0]] = True
        nearest = np.argmin(norm[sl], axis=0)
        near_ok = ok[nearest, np.arange(len(tracks))] & claimed[nearest] & (blob_of < 0)
        for t in np.nonzero(blob_of >= 0)[0].tolist():
            out[t][sid] = int(blob_of[t])
        # A track left without a blob whose nearest is another track's: this person is probably hidden
        # behind it. It explains the blob (no birth from it) but its bearing is the other person's.
        for t in np.nonzero(near_ok)[0].tolist():
            shared[t][sid] = int(nearest[t])
    return out, shared


def _look_cost(sid: str, hist_sqrt: FloatArray, tracks: list[TrackRecord], ok: npt.NDArray[np.bool_]) -> FloatArray:
    """(n_blobs, n_tracks) colour dissimilarity (1 - Bhattacharyya) of each blob to each track's look there.

    Two people meeting swap blobs by position alone; by their shirts they seldom do. Tracks without a look in
    this view cost nothing extra.
    """
    bc = bhattacharyya(hist_sqrt, [tr.looks.get(sid) for tr in tracks])
    return np.where(ok & ~np.isnan(bc), 1.0 - np.nan_to_num(bc), 0.0)
