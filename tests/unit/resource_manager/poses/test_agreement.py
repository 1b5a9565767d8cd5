"""A camera whose blobs stop agreeing with the people the other cameras place is reported, with its residual."""

from __future__ import annotations

import math

import numpy as np

from common.schema import SensorAgreement
from resource_manager.poses.agreement import Agreement, AgreementParams
from resource_manager.track.tracker import TrackSnapshot
from tests.unit.resource_manager.synth import ViewSpec, snapshot, stack_views

CAMERAS = {"c1": (0.0, 0.0), "c2": (10.0, 0.0), "c3": (5.0, 10.0)}
PEOPLE = [(3.0, 4.0), (6.0, 3.0), (7.0, 6.0)]


def _view(sid: str, yaw_error_rad: float = 0.0) -> ViewSpec:
    x, y = CAMERAS[sid]
    bearings = np.array([math.atan2(py - y, px - x) for px, py in PEOPLE]) + yaw_error_rad
    n = bearings.size
    return ViewSpec(
        sensor_id=sid,
        origin_xy=np.array([x, y]),
        z_m=2.0,
        sigma_rad=0.005,
        bearing_rad=bearings,
        width_rad=np.full(n, 0.05),
        top_elev_rad=np.zeros(n),
        hist=None,
        local_id=np.arange(n, dtype=np.int64),
    )


def _people(
    views: list[str], pair: tuple[str, ...] = (), where: list[tuple[float, float]] = PEOPLE
) -> list[TrackSnapshot]:
    """The published people (at ``where``), each placed at this tick by the blobs of ``views`` (``pair``: the best
    pair of them)."""
    return [
        snapshot(i, (px, py), track_id=f"m-{i}", sensors=pair or tuple(views[:2]), views=tuple(views))
        for i, (px, py) in enumerate(where)
    ]


def _run(yaw_error_rad: float, seconds: int = 12) -> dict[str, tuple[float, bool, float]]:
    agree = Agreement(AgreementParams(window_s=10.0, min_blobs=10))
    for k in range(seconds * 2):
        views = stack_views([_view("c1"), _view("c2"), _view("c3", yaw_error_rad)])
        agree.update(k * 500_000_000, views, _people(["c1", "c2", "c3"], pair=("c1", "c3")))
    return {a.sensor_id: (a.residual_m, a.disagrees, a.unexplained_frac) for a in agree.report()}


def test_cameras_in_place_agree() -> None:
    out = _run(0.0)
    assert set(out) == {"c1", "c2", "c3"}
    assert all(r < 0.01 and not bad for r, bad, _ in out.values())


def test_a_turned_camera_disagrees_with_its_residual() -> None:
    out = _run(math.radians(6.0))
    r3, bad3, _ = out["c3"]
    assert bad3 and 0.5 < r3 <= 1.0  # 6 deg at 4-7 m: 0.4-0.8 m off the people
    assert not out["c1"][1] and not out["c2"][1]
    report = Agreement().report()
    assert report == []


def test_a_camera_turned_away_from_everyone_is_all_unexplained() -> None:
    residual, bad, unexplained = _run(math.radians(60.0))["c3"]
    assert bad and unexplained > 0.5 and residual == AgreementParams().gate_m


def test_only_tracks_the_others_placed_count() -> None:
    agree = Agreement(AgreementParams(min_blobs=1))
    views = stack_views([_view("c3", math.radians(6.0))])
    agree.update(0, views, _people(["c3", "c1"]))  # one other camera: the track rests on c3 too
    assert agree.report() == []


def test_a_camera_in_every_best_pair_is_checked_against_the_others_blobs() -> None:
    """What checks a camera is which cameras' blobs placed each person, not the pair the error model ranks best for
    them: a camera in every best pair (the nearest one) is still checked, and in place it agrees."""
    agree = Agreement(AgreementParams(min_blobs=1))
    views = stack_views([_view("c1"), _view("c2"), _view("c3")])
    agree.update(0, views, _people(["c1", "c2", "c3"], pair=("c3", "c1")))
    out = {a.sensor_id: a for a in agree.report()}
    assert out["c3"].blobs == len(PEOPLE) and out["c3"].residual_m < 0.01 and out["c3"].unexplained_frac == 0.0


def test_blobs_of_people_only_this_camera_helped_place_test_nothing() -> None:
    """Of a camera's blobs, those showing a person the others alone do not place are left out, not counted as
    unexplained: a camera in place beside such people agrees."""
    agree = Agreement(AgreementParams(min_blobs=1))
    views = stack_views([_view("c3")])
    people = _people(["c1", "c2", "c3"])
    people[1:] = _people(["c3", "c1"])[1:]  # two of the three rest on c3 too
    agree.update(0, views, people)
    (c3,) = agree.report()
    assert c3.blobs == 1 and c3.residual_m < 0.01 and c3.unexplained_frac == 0.0


def _ranged_view(
    sid: str, people: list[tuple[float, float]], turn_rad: float = 0.0, fov: float | None = None
) -> ViewSpec:
    """A camera at the origin whose blobs give each person's bearing (turned by ``turn_rad``) and feet distance."""
    xy = np.array(people)
    n = len(xy)
    return ViewSpec(
        sensor_id=sid,
        origin_xy=np.zeros(2),
        z_m=2.0,
        sigma_rad=0.005,
        bearing_rad=np.arctan2(xy[:, 1], xy[:, 0]) + turn_rad,
        width_rad=np.full(n, 0.05),
        top_elev_rad=np.zeros(n),
        hist=None,
        local_id=np.arange(n, dtype=np.int64),
        mono_range_m=np.hypot(xy[:, 0], xy[:, 1]),
        mono_sigma_m=np.full(n, 0.2),
        fov=(0.0, fov) if fov is not None else None,
    )


RAY_PEOPLE = [(7.0, 0.0), (14.0, 14.0 * math.tan(math.radians(5.0)))]
"""Two people on nearly one line from the origin: a ray to the first turned by 5 degrees passes through the second."""


def _one_tick(c3: ViewSpec, people: list[tuple[float, float]], fov: float | None = None) -> dict[str, SensorAgreement]:
    agree = Agreement(AgreementParams(min_blobs=1))
    others = [_ranged_view(s, people, fov=fov) for s in ("c1", "c2")]
    agree.update(0, stack_views([*others, c3]), _people(["c1", "c2", "c3"], where=people))
    return {a.sensor_id: a for a in agree.report()}


def test_a_blob_with_feet_is_checked_against_the_person_at_its_distance_not_anyone_its_ray_passes() -> None:
    """A turned camera's ray through a crowd passes near somebody; its feet distance says whom it shows."""
    assert _one_tick(_ranged_view("c3", RAY_PEOPLE), RAY_PEOPLE)["c3"].residual_m < 0.01
    turned = _one_tick(_ranged_view("c3", RAY_PEOPLE, turn_rad=math.radians(5.0)), RAY_PEOPLE)["c3"]
    assert turned.disagrees and turned.residual_m > 0.5


def test_a_blob_whose_feet_no_two_others_see_is_no_evidence() -> None:
    """A blob that finds nobody where no two other cameras look (someone only it sees) is left out, not counted
    as unexplained."""
    people = [(7.0, 0.0)]
    c3 = _ranged_view("c3", [(7.0, 0.0), (0.0, 6.0)])  # the second: straight up the y axis, out of c1's and c2's view
    out = _one_tick(c3, people, fov=math.radians(30.0))["c3"]
    assert out.blobs == 1 and out.unexplained_frac == 0.0


def _turned_at(turn_rad: float, at_s: float, seconds: float) -> list[SensorAgreement]:
    """c3's report each second, turned by ``turn_rad`` from ``at_s`` on (2 ticks a second)."""
    agree = Agreement(AgreementParams(window_s=10.0, min_blobs=10, settle_s=30.0))
    reports = []
    for k in range(int(seconds * 2)):
        turn = turn_rad if k / 2 >= at_s else 0.0
        views = stack_views([_view("c1"), _view("c2"), _view("c3", turn)])
        agree.update(k * 500_000_000, views, _people(["c1", "c2", "c3"]))
        if k % 2:
            reports.append(next(a for a in agree.report() if a.sensor_id == "c3"))
    return reports


def test_a_camera_turned_while_running_is_named_against_its_own_residual_in_place() -> None:
    """A turn too small for the absolute threshold (1.5 degrees: 0.1-0.2 m at these distances) is named once the
    camera's own residual in place (here about zero) has been learned; before the turn nothing is named."""
    reports = _turned_at(math.radians(1.5), at_s=60.0, seconds=80.0)
    before, after = reports[:59], reports[-5:]
    assert not any(a.disagrees for a in before)
    assert before[-1].settled_m is not None and before[-1].settled_m < 0.01
    assert all(a.disagrees and 0.05 < a.residual_m < AgreementParams().disagree_m for a in after)


def test_the_same_turn_from_the_start_is_its_own_residual_and_a_far_one_has_none() -> None:
    """Turned from the start, the small turn is what the camera learns as its own (nothing to compare with: only
    the absolute threshold judges it); a camera far off from the start learns nothing and is named throughout."""
    small = _turned_at(math.radians(1.5), at_s=0.0, seconds=60.0)
    assert not any(a.disagrees for a in small) and small[-1].settled_m is not None
    far = _turned_at(math.radians(6.0), at_s=0.0, seconds=60.0)
    assert all(a.disagrees for a in far[10:]) and far[-1].settled_m is None
