"""The manager's outgoing messages, built from the stages' values: tracks, track sets, pair choices, view plans
and PTZ commands.

Every number is brought inside the range its schema field declares (:mod:`common.schema`), read from the schema
itself, so a vague or diverging estimate is published clipped instead of failing the whole message's encoding;
lists are cut to the schema's lengths. Pure: values in, messages out.
"""

from __future__ import annotations

import math
import typing
from collections.abc import Sequence
from functools import cache

import msgspec

from common.angles import wrap_angle
from common.numbers import clip
from common.schema import (
    MAX_SENSORS,
    MAX_TRACKS,
    PairChoice,
    PairEntry,
    PtzCommand,
    Track,
    TrackSet,
    ViewPlan,
)
from resource_manager.plan.planner import PlanGoal
from resource_manager.serve.lag import LaggedInstant
from resource_manager.serve.ptz import PtzAim
from resource_manager.track.tracker import TrackSnapshot

__all__ = ["lagged_set", "pair_choice", "ptz_command", "track_message", "track_set", "view_plan"]


@cache
def _bounds(struct: type[msgspec.Struct], name: str) -> tuple[float, float]:
    """The ``ge``/``le`` bounds the schema declares for ``struct.name`` (infinite where it declares none)."""
    hint = typing.get_type_hints(struct, include_extras=True)[name]
    lo, hi = -math.inf, math.inf
    for meta in typing.get_args(hint)[1:]:
        if isinstance(meta, msgspec.Meta):
            lo = meta.ge if meta.ge is not None else lo
            hi = meta.le if meta.le is not None else hi
    return lo, hi


def _fit(struct: type[msgspec.Struct], name: str, v: float) -> float:
    """``v`` clipped to the schema's range of ``struct.name`` (NaN stays NaN)."""
    return clip(v, *_bounds(struct, name))


def _fit_int(struct: type[msgspec.Struct], name: str, v: int) -> int:
    lo, hi = _bounds(struct, name)
    return int(min(max(v, lo), hi))


def track_message(manager_id: str, tr: TrackSnapshot, seq: int, track_id: str = "") -> Track:
    """The message of one track in the TrackSet ``seq`` (``track_id``: the id to publish it under, default its
    own). A track published under an id it was confirmed with later (``publish_lag_s``) is published as
    confirmed then."""
    tid = track_id or tr.track_id or f"{manager_id}-t{tr.serial}"
    state = tr.state
    if track_id and state == "tentative":
        state = "confirmed" if tr.detected else "coasting"
    x, y, vx, vy = tr.x.tolist()[:4]  # plain floats: np.clip on scalars costs ~10x
    (pxx, pxy), (_, pyy) = tr.p_xy.tolist()
    return Track(
        manager_id=manager_id,
        seq=seq,
        stamp_ns=tr.t_ns,
        track_id=tid,
        x_m=_fit(Track, "x_m", x),
        y_m=_fit(Track, "y_m", y),
        height_m=_fit(Track, "height_m", tr.height_m),
        vx_mps=_fit(Track, "vx_mps", vx),
        vy_mps=_fit(Track, "vy_mps", vy),
        cov_xx_m2=_fit(Track, "cov_xx_m2", pxx),
        cov_xy_m2=_fit(Track, "cov_xy_m2", pxy),
        cov_yy_m2=_fit(Track, "cov_yy_m2", pyy),
        state=state,
        method=tr.method,
        sensors=list(tr.sensors)[:MAX_SENSORS],
        predicted_error_m=_fit(Track, "predicted_error_m", tr.predicted_error_m),
        age_s=_fit(Track, "age_s", (tr.t_ns - tr.born_ns) / 1e9),
        hits=_fit_int(Track, "hits", tr.hits),
        misses=_fit_int(Track, "misses", tr.misses),
    )


def track_set(manager_id: str, seq: int, t_ns: int, tracks: Sequence[Track], sensors_used: Sequence[str]) -> TrackSet:
    return TrackSet(
        manager_id=manager_id,
        seq=seq,
        stamp_ns=t_ns,
        tracks=list(tracks[:MAX_TRACKS]),
        sensors_used=list(sensors_used[:MAX_SENSORS]),
    )


def lagged_set(manager_id: str, instant: LaggedInstant) -> TrackSet:
    """The TrackSet of an instant held back by ``publish_lag_s``."""
    tracks = [track_message(manager_id, tr, instant.seq, tid) for tr, tid in instant.tracks[:MAX_TRACKS]]
    return track_set(manager_id, instant.seq, instant.t_ns, tracks, instant.sensors_used)


def pair_choice(manager_id: str, seq: int, t_ns: int, entries: Sequence[PairEntry]) -> PairChoice:
    return PairChoice(manager_id=manager_id, seq=seq, stamp_ns=t_ns, choices=list(entries[:MAX_TRACKS]))


def view_plan(manager_id: str, seq: int, t_ns: int, g: PlanGoal) -> ViewPlan:
    return ViewPlan(
        manager_id=manager_id,
        seq=seq,
        stamp_ns=t_ns,
        sensor_id=g.sensor_id,
        partner_id=g.partner_id,
        track_id=g.track_id,
        goal_x_m=g.goal_xy[0],
        goal_y_m=g.goal_xy[1],
        baseline_m=g.baseline_m,
        phi1_rad=_fit(ViewPlan, "phi1_rad", g.phi1_rad),
        predicted_error_m=g.predicted_error_m,
        current_error_m=g.current_error_m,
    )


def ptz_command(manager_id: str, seq: int, t_ns: int, aim: PtzAim) -> PtzCommand:
    return PtzCommand(
        manager_id=manager_id,
        seq=seq,
        stamp_ns=t_ns,
        sensor_id=aim.sensor_id,
        pan_rad=float(wrap_angle(aim.pan_rad)),
        tilt_rad=_fit(PtzCommand, "tilt_rad", aim.tilt_rad),
        zoom=float(aim.zoom),
        track_id=aim.track_id,
    )
