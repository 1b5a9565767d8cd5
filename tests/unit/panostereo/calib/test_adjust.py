"""The bundle adjustment moves a camera back where its rays say it is."""

from __future__ import annotations

import math

import numpy as np

from panostereo.calib.adjust import Tolerance, adjust, ray_distances
from panostereo.calib.associate import HeightPrior, associate, world_rays
from panostereo.calib.poses import pose_change
from tests.unit.panostereo.calib.test_associate import _rays


def _walk() -> np.ndarray:
    rng = np.random.default_rng(0)
    return np.column_stack([rng.uniform(2, 10, 40), rng.uniform(2, 10, 40), rng.uniform(1.6, 1.9, 40)])


def test_a_turned_camera_is_adjusted_back_and_its_residual_drops() -> None:
    people = _walk()
    parts = [_rays(cid, people) for cid in ("cam-a", "cam-b", "cam-c")]
    cams, truth = [p[0] for p in parts], [p[1] for p in parts]
    # One person per instant, so the association is unambiguous; cam-c starts 0.2 m and 1 deg off.
    cams = [
        type(c)(**{**{f: getattr(c, f) for f in c.__slots__}, "instant": np.arange(c.n, dtype=np.int64)}) for c in cams
    ]
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
    assert abs(res.mean_height_m - float(people[:, 2].mean())) < 0.02
