"""The bundle adjustment moves a camera back where its rays say it is."""

from __future__ import annotations

import math

import numpy as np

from panostereo.calib.adjust import Tolerance, adjust, ray_distances
from panostereo.calib.associate import HeightPrior, associate, world_rays
from panostereo.calib.observe import CameraRays
from panostereo.calib.poses import CameraPose, pose_change
from tests.unit.panostereo.calib.test_associate import _rays


def _walk() -> np.ndarray:
    rng = np.random.default_rng(0)
    return np.column_stack([rng.uniform(2, 10, 40), rng.uniform(2, 10, 40), rng.uniform(1.6, 1.9, 40)])


def _three(people: np.ndarray) -> tuple[list[CameraRays], list[CameraPose]]:
    """Three true cameras' rays of ``people``, one person per instant (the association is unambiguous)."""
    parts = [_rays(cid, people) for cid in ("cam-a", "cam-b", "cam-c")]
    cams = [
        type(c)(**{**{f: getattr(c, f) for f in c.__slots__}, "instant": np.arange(c.n, dtype=np.int64)})
        for c, _ in parts
    ]
    return cams, [p[1] for p in parts]


def test_a_turned_camera_is_adjusted_back_and_its_residual_drops() -> None:
    people = _walk()
    cams, truth = _three(people)
    # cam-c starts 0.2 m and 1 deg off.
    start = list(truth)
    start[2] = truth[2].moved([0.0, math.radians(1.0), 0.0, 0.2, 0.0, 0.0])
    assoc = associate(world_rays(cams, start), 1.0, HeightPrior(), 100.0)
    assert assoc.person.shape[0] == people.shape[0]
    before = np.nanmedian(ray_distances(cams, start, assoc, assoc.person)[0][assoc.member_camera == 2])
    res = adjust(cams, start, [2], assoc, prior=HeightPrior(), tolerance=Tolerance(), scale_m=0.5)
    moved, turned = pose_change(truth[2], res.poses[2])
    assert moved < 0.01 and math.degrees(turned) < 0.05
    assert res.poses[0] is start[0] and res.poses[1] is start[1]  # the others were not free
    after = np.nanmedian(ray_distances(cams, res.poses, assoc, res.person)[0][assoc.member_camera == 2])
    assert after < 0.01 < before
    assert abs(res.mean_height_m - float(np.median(people[:, 2]))) < 0.02


def test_people_of_unusual_heights_do_not_tilt_the_cameras() -> None:
    # Two people, one short and one tall, each seen at many instants: their heights are far from the population's
    # mean, and nothing about the cameras is wrong. A fit that pulled each person-instant's height towards the
    # others' would tilt the cameras to make the tall one shorter and the short one taller.
    rng = np.random.default_rng(1)
    places = np.column_stack([rng.uniform(2, 10, 60), rng.uniform(2, 10, 60)])
    people = np.column_stack([places, np.where(np.arange(60) % 2 == 0, 1.5, 2.0)])
    cams, truth = _three(people)
    assoc = associate(world_rays(cams, truth), 0.3, HeightPrior(), 100.0)
    res = adjust(cams, truth, [1, 2], assoc, prior=HeightPrior(), tolerance=Tolerance(), scale_m=0.15)
    for ci in (1, 2):
        moved, turned = pose_change(truth[ci], res.poses[ci])
        assert moved < 0.005 and math.degrees(turned) < 0.02, (ci, moved, math.degrees(turned))


def test_the_jacobian_gives_the_costs_gradient() -> None:
    # The cameras' parameters alone are the unknowns; each person is placed where their rays meet. The Jacobian
    # (the people's motion through their normal equations) must give the gradient of the cost, or the adjustment
    # stops where the cameras are not best: checked against finite differences of the cost, off the optimum.
    from scipy.optimize import approx_fprime

    from panostereo.calib import adjust as adj

    cams, truth = _three(_walk())
    assoc = associate(world_rays(cams, truth), 1.0, HeightPrior(), 100.0)
    order = np.argsort(assoc.member_camera, kind="stable")
    mc, mp = assoc.member_camera[order], assoc.member_person[order]
    basis = []
    for rays in ("foot", "head"):
        d = np.concatenate(
            [getattr(cams[c], rays)[i][None] for c, i in zip(mc, assoc.member_index[order], strict=True)]
        )
        e1, e2 = adj._basis(d)
        basis.append(np.stack([e1, e2], axis=1) * 10.0)  # 1 / point_sigma_m
    offset, width, _ = adj._layout(truth, [1, 2], Tolerance())
    fit = adj._Projected(
        truth, [1, 2], mc, mp, assoc.person.shape[0], (basis[0], basis[1]), held=truth,
        layout=(offset, width, np.ones(12)), f_scale=1e6, height=(1.75, 0.5),
    )  # fmt: skip
    x = np.random.default_rng(2).normal(scale=0.01, size=12)
    cost = lambda z: 0.5 * float(np.sum(fit.residuals(z) ** 2))  # noqa: E731 - the cost scipy minimises
    gradient = fit.jacobian(x).T @ fit.residuals(x)
    assert np.allclose(gradient, approx_fprime(x, cost, 1e-7), rtol=0.02, atol=1e-3 * np.abs(gradient).max())
    # The centres' columns are exact (a ray's direction does not depend on where its camera is); the turns' drop
    # the term of the people's rays turning with their camera (Kaufman's approximation: the gradient stays exact).
    centres = [3, 4, 5, 9, 10, 11]
    step = 1e-6 * np.eye(12)
    numeric = np.column_stack([(fit.residuals(x + step[k]) - fit.residuals(x - step[k])) / 2e-6 for k in centres])
    assert np.allclose(fit.jacobian(x)[:, centres], numeric, atol=1e-4 * np.abs(numeric).max())
