"""The measurement update: every track with its assigned views, the pair that reports it, its looks and links."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from resource_manager.track.filter import TrackFilter
from resource_manager.track.model import TrackModel
from resource_manager.track.motion import MotionModel
from resource_manager.track.state import TrackRecord
from resource_manager.track.update import Assigned, Tick, Updater
from tests.unit.resource_manager.synth import stack_views, view

CAMS = {"p1": (0.0, 0.0), "p2": (8.0, 0.0), "p3": (8.0, 6.0)}


def _tick(person: tuple[float, float]) -> Tick:
    sids = sorted(CAMS)
    views = stack_views(
        [dataclasses.replace(view(s, CAMS[s], [(person[0], person[1], 1.75, 1)]), point_var_m2=0.01) for s in sids]
    )
    return Tick(views, dict.fromkeys(sids, (1.0, 1.0)), {}, np.ones(len(sids)))


@pytest.mark.parametrize("mode", ["model", "paper"])
def test_a_track_is_pulled_onto_its_views_reports_its_best_pair_and_learns_its_looks(mode: str) -> None:
    f = TrackFilter(MotionModel(0.8, 2.0), 0.05)
    f.add(np.array([[3.3, 2.2, 0.0, 0.0]]), np.eye(4)[None] * 0.09, height=np.array([1.7]),
          height_var=np.array([0.02]), logodds=np.array([3.0]), t_ns=0)  # fmt: skip
    tr = TrackRecord(serial=1, born_ns=0, track_id="m-1", confirmed=True)
    updater = Updater(TrackModel(mode=mode), width_rel_sigma=0.1, pair_choice="error_model")
    got = [Assigned(sid, 0) for sid in sorted(CAMS)]
    out = updater.update(f, [tr], [got], _tick((3.0, 2.0)), t_ns=5)
    assert math.hypot(f.x[0, 0] - 3.0, f.x[0, 1] - 2.0) < 0.1  # from 0.36 m off, sure of where it was
    assert f.height[0] == pytest.approx(1.75, abs=0.03)
    assert tr.detected and tr.hits == 1 and tr.seen_ns == 5 and set(tr.sensors) <= set(CAMS)
    assert [e.track_id for e in out.pair_entries] == ["m-1"] and out.kept == [got]
    assert set(tr.looks) == set(CAMS) and tr.links == dict.fromkeys(CAMS, 0)


def test_a_track_no_view_detects_coasts() -> None:
    f = TrackFilter(MotionModel(0.8, 2.0), 0.05)
    f.add(np.array([[3.0, 2.0, 0.0, 0.0]]), np.eye(4)[None] * 0.01, height=np.array([1.7]),
          height_var=np.array([0.02]), logodds=np.array([3.0]), t_ns=0)  # fmt: skip
    tr = TrackRecord(serial=1, born_ns=0, confirmed=True, detected=True)
    out = Updater(TrackModel(), 0.1, "error_model").update(f, [tr], [[]], _tick((3.0, 2.0)), t_ns=5)
    assert not tr.detected and tr.misses == 1 and tr.state() == "coasting" and out.pair_entries == []


def test_each_view_looks_for_a_track_where_the_other_views_put_it() -> None:
    """Track 0 has a blob from every view: each view looks for it where the other two put it (on its person, from
    0.36 m off). Track 1 has one blob, from p2: p2 looks for it where it was predicted, the others where p2's blob
    puts it. Track 2 has none: every view looks where it was predicted. The filter keeps its prediction."""
    f = TrackFilter(MotionModel(0.8, 2.0), 0.05)
    x0 = np.array([[5.3, 1.7, 0.0, 0.0], [5.2, 1.2, 0.0, 0.0], [6.0, 4.0, 0.0, 0.0]])
    f.add(x0, np.repeat(np.eye(4)[None] * 0.09, 3, axis=0), height=np.full(3, 1.7), height_var=np.full(3, 0.02),
          logodds=np.full(3, 3.0), t_ns=0)  # fmt: skip
    tick = _tick((5.0, 1.5))  # any two of the views cross there at 39 deg or more
    rows = tick.views.rows
    updater = Updater(TrackModel(), width_rel_sigma=0.1, pair_choice="error_model")
    xy, cov = updater.leave_one_out(f, [[Assigned(s, 0) for s in sorted(CAMS)], [Assigned("p2", 0)], []], tick)
    assert xy.shape == (3, 3, 2) and cov.shape == (3, 3, 2, 2)
    for sid in CAMS:
        assert math.hypot(xy[rows[sid], 0, 0] - 5.0, xy[rows[sid], 0, 1] - 1.5) < 0.15
        assert np.trace(cov[rows[sid], 0]) < 0.2 * np.trace(f.p[0, :2, :2])
    assert len({tuple(np.round(xy[v, 0], 9)) for v in range(3)}) == 3  # each without its own blob
    assert xy[rows["p2"], 1] == pytest.approx(x0[1, :2]) and cov[rows["p2"], 1] == pytest.approx(f.p[1, :2, :2])
    assert xy[rows["p1"], 1] == pytest.approx(xy[rows["p3"], 1])
    assert not np.allclose(xy[rows["p1"], 1], x0[1, :2])  # p2's bearing moved it
    assert xy[:, 2] == pytest.approx(np.repeat(x0[None, 2, :2], 3, axis=0))
    assert f.x == pytest.approx(x0)  # nothing kept
