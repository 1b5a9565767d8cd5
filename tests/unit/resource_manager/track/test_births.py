"""Births: blobs no track explains, paired across views (Eq. 7) and judged by every view."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from resource_manager.stereo.match import MatchParams
from resource_manager.stereo.matchers import get_matcher
from resource_manager.track.births import BirthParams, Hypothesis, find_births
from resource_manager.track.model import Scene, TrackModel
from resource_manager.track.observe import TrackTable
from tests.unit.resource_manager.synth import ViewSpec, stack_views, view

CAMS = {"p1": (0.0, 0.0), "p2": (8.0, 0.0), "p3": (8.0, 6.0), "p4": (0.0, 6.0)}
PARAMS = BirthParams(MatchParams(), threshold=0.1, matcher=get_matcher("greedy"), max_pairs=16, width_rel_sigma=0.1)
MODEL = TrackModel()
SIGMA_M = MODEL.body_sigma_m
NOBODY = TrackTable(np.zeros((0, 2)), np.zeros((0, 2, 2)), np.zeros(0), np.zeros(0))


def _tracked(x: float, y: float, height: float) -> TrackTable:
    return TrackTable(np.array([[x, y]]), np.eye(2)[None] * 0.01, np.array([height]), np.array([0.01]))


def _births(people: list[tuple[float, float, float, int]], tracks: TrackTable) -> list[Hypothesis]:
    views = stack_views([dataclasses.replace(view(sid, o, people), point_var_m2=SIGMA_M**2) for sid, o in CAMS.items()])
    return find_births(
        views,
        np.ones(views.n, dtype=bool),
        tracks,
        MODEL,
        scene=Scene(),
        params=PARAMS,
        tick=0,
        min_evidence=math.log(9.0),
    )


def test_one_person_seen_by_every_view_is_one_birth_with_every_views_blob() -> None:
    (h,) = _births([(3.0, 2.0, 1.75, 1)], NOBODY)
    assert math.hypot(h.fix.xy[0] - 3.0, h.fix.xy[1] - 2.0) < 0.05
    assert h.blobs == {"p1": 0, "p2": 0, "p3": 0, "p4": 0}
    assert h.evidence > math.log(9.0)


def test_two_people_are_two_births_and_nobody_is_started_beside_a_track() -> None:
    people = [(2.0, 2.0, 1.75, 1), (6.0, 4.0, 1.6, 2)]
    hyps = _births(people, NOBODY)
    assert sorted((round(h.fix.xy[0]), round(h.fix.xy[1])) for h in hyps) == [(2, 2), (6, 4)]
    (h,) = _births(people, _tracked(6.1, 4.0, 1.6))
    assert (round(h.fix.xy[0]), round(h.fix.xy[1])) == (2, 2)


def _one_camera(p2_fov: tuple[float, float] | None, mono_sigma_m: float = 0.2) -> list[Hypothesis]:
    """A person at (3, 2) whom calibrated camera p1 sees with its feet on the floor; p2 has no blob of them and
    points ``p2_fov`` (None: sees all round)."""
    seen = view("p1", (0.0, 0.0), [(3.0, 2.0, 1.75, 1)])
    p1 = dataclasses.replace(seen, mono_range_m=np.array([math.hypot(3.0, 2.0)]), mono_sigma_m=np.array([mono_sigma_m]))
    p2 = dataclasses.replace(view("p2", (8.0, 0.0), []), fov=p2_fov)
    views = stack_views([dataclasses.replace(v, point_var_m2=SIGMA_M**2) for v in (p1, p2)])
    return find_births(
        views,
        np.ones(views.n, dtype=bool),
        NOBODY,
        MODEL,
        scene=Scene(),
        params=PARAMS,
        tick=0,
        min_evidence=0.0,
    )


def test_where_one_camera_alone_sees_its_feet_on_the_floor_start_a_person() -> None:
    (h,) = _one_camera(p2_fov=(0.0, 0.5))  # p2 looks away (+x): nobody else can see the spot
    assert h.blobs == {"p1": 0}
    assert math.hypot(h.fix.xy[0] - 3.0, h.fix.xy[1] - 2.0) < 0.05
    assert h.fix.sensors == ("p1",)


def test_one_camera_alone_starts_nobody_where_another_has_a_clear_view_or_the_feet_are_vague() -> None:
    assert _one_camera(p2_fov=None) == []  # p2 sees the spot and has nothing there: stereo's to start
    assert _one_camera(p2_fov=(0.0, 0.5), mono_sigma_m=2.0 * MODEL.publish_sigma_m) == []


def test_a_box_the_pictures_side_cuts_starts_nobody_alone() -> None:
    """Its centre is not its person's: it may support a birth, never define one."""
    seen = view("p1", (0.0, 0.0), [(3.0, 2.0, 1.75, 1)])
    p1 = dataclasses.replace(
        seen, mono_range_m=np.array([math.hypot(3.0, 2.0)]), mono_sigma_m=np.array([0.05]), side_cut=np.array([1.0])
    )
    views = stack_views([dataclasses.replace(p1, point_var_m2=SIGMA_M**2)])
    unexplained = np.ones(views.n, dtype=bool)
    kw = {"scene": Scene(), "params": PARAMS, "tick": 0, "min_evidence": 0.0}
    assert find_births(views, unexplained, NOBODY, MODEL, **kw) == []  # type: ignore[arg-type]
    whole = stack_views([dataclasses.replace(seen, mono_range_m=p1.mono_range_m, mono_sigma_m=p1.mono_sigma_m,
                                             point_var_m2=SIGMA_M**2)])  # fmt: skip
    assert len(find_births(whole, unexplained, NOBODY, MODEL, **kw)) == 1  # type: ignore[arg-type]


def test_a_multi_view_detector_that_boxed_a_new_person_in_some_views_did_not_miss_them_in_the_others() -> None:
    """A new person's blobs in two of four views. Each camera's own detector: the other two missed them, which counts
    against them. One multi-view detector in all four: it found them; its other views' lack of a blob says nothing."""

    def evidence(detector: str) -> float:
        def one(sid: str, origin: tuple[float, float]) -> ViewSpec:
            seen = view(sid, origin, [(3.0, 2.0, 1.75, 1)] if sid in ("p1", "p2") else [])
            return dataclasses.replace(seen, point_var_m2=SIGMA_M**2, shared_detector=detector)

        specs = [one(sid, o) for sid, o in CAMS.items()]
        views = stack_views(specs)
        (h,) = find_births(views, np.ones(views.n, dtype=bool), NOBODY, MODEL, scene=Scene(), params=PARAMS, tick=0,
                           min_evidence=-100.0)  # fmt: skip
        assert set(h.blobs) == {"p1", "p2"}
        return h.evidence

    assert evidence("mv") - evidence("") == pytest.approx(-2.0 * math.log1p(-MODEL.p_detect), rel=1e-6)
