"""A camera whose blobs stop agreeing with the people the other cameras place is reported, with its residual."""

from __future__ import annotations

import math

import numpy as np

from common.schema import Track
from resource_manager.poses.agreement import Agreement, AgreementParams
from tests.unit.resource_manager.synth import ViewSpec, stack_views

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


def _tracks(sensors: list[str]) -> list[Track]:
    return [
        Track(
            manager_id="m",
            seq=1,
            stamp_ns=0,
            track_id=f"m-{i}",
            x_m=px,
            y_m=py,
            height_m=1.7,
            vx_mps=0.0,
            vy_mps=0.0,
            cov_xx_m2=0.01,
            cov_xy_m2=0.0,
            cov_yy_m2=0.01,
            state="confirmed",
            method="least_squares",
            sensors=sensors,
        )
        for i, (px, py) in enumerate(PEOPLE)
    ]


def _run(yaw_error_rad: float, seconds: int = 12) -> dict[str, tuple[float, bool, float]]:
    agree = Agreement(AgreementParams(window_s=10.0, min_blobs=10))
    for k in range(seconds * 2):
        views = stack_views([_view("c1"), _view("c2"), _view("c3", yaw_error_rad)])
        agree.update(k * 500_000_000, views, _tracks(["c1", "c2", "c3"]))
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
    agree.update(0, views, _tracks(["c3", "c1"]))  # one other camera: the track rests on c3 too
    assert agree.report() == []
