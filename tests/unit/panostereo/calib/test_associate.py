"""Rays of one instant grouped into people with the cameras' poses."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from panostereo.calib.associate import HeightPrior, associate, triangulate, world_rays
from panostereo.calib.observe import CameraRays
from panostereo.calib.poses import CameraPose
from tests.unit.panostereo.calib.synth import true_cameras

PEOPLE = np.array([[3.0, 4.0, 1.7], [6.0, 7.0, 1.8], [8.0, 3.0, 1.65]])


def _rays(cid: str, people: np.ndarray, extra: np.ndarray | None = None) -> tuple[CameraRays, CameraPose]:
    cam = true_cameras()[cid]
    pose = CameraPose(np.array(cam.r), cam.center_world, level=False)
    feet = people.copy()
    feet[:, 2] = 0.0
    foot = (feet - pose.centre_m) @ pose.rotation.T
    head = (people - pose.centre_m) @ pose.rotation.T
    if extra is not None:  # a clutter box: rays towards nobody
        foot = np.vstack([foot, extra[0]])
        head = np.vstack([head, extra[1]])
    n = foot.shape[0]
    rays = CameraRays(
        sensor_id=cid,
        info=None,  # type: ignore[arg-type]
        pose=pose,
        point_sigma_m=0.1,
        instant=np.zeros(n, dtype=np.int64),
        track=np.arange(n, dtype=np.int64),
        foot=foot / np.linalg.norm(foot, axis=1, keepdims=True),
        head=head / np.linalg.norm(head, axis=1, keepdims=True),
        feet_ok=np.ones(n, dtype=bool),
        head_ok=np.ones(n, dtype=bool),
    )
    return rays, pose


def test_each_person_is_one_group_of_one_blob_per_camera() -> None:
    clutter = (np.array([0.3, 0.2, 1.0]), np.array([0.3, 0.0, 1.0]))
    parts = [_rays("cam-a", PEOPLE), _rays("cam-b", PEOPLE[::-1], clutter), _rays("cam-c", PEOPLE)]
    cams, poses = [p[0] for p in parts], [p[1] for p in parts]
    a = associate(world_rays(cams, poses), 0.3, HeightPrior(), 100.0)
    assert a.person.shape[0] == 3
    for pid in range(3):
        cams_of = a.member_camera[a.member_person == pid]
        assert sorted(cams_of.tolist()) == [0, 1, 2]
    assert 3 not in a.member_index[a.member_camera == 1].tolist()  # the clutter blob joined nobody
    found = a.person[np.argsort(a.person[:, 0])]
    assert np.allclose(found, PEOPLE[np.argsort(PEOPLE[:, 0])], atol=0.05)


def test_triangulate_recovers_the_person_and_its_height() -> None:
    parts = [_rays("cam-a", PEOPLE[:1]), _rays("cam-c", PEOPLE[:1])]
    r = world_rays([p[0] for p in parts], [p[1] for p in parts])
    ((x, y, h),) = triangulate(r, [np.array([0, 1])], HeightPrior())
    assert (x, y, h) == pytest.approx(tuple(PEOPLE[0]), abs=0.02)


def test_a_gate_too_narrow_for_the_poses_groups_nobody() -> None:
    a_rays, a_pose = _rays("cam-a", PEOPLE)
    c_rays, c_pose = _rays("cam-c", PEOPLE)
    off = c_pose.moved([0.0, 0.05, 0.0, 0.0, 0.0, 0.0])  # cam-c turned by 3 deg: its rays miss by ~0.5 m
    assert associate(world_rays([a_rays, c_rays], [a_pose, off]), 0.1, HeightPrior(), 100.0).person.shape[0] == 0


def test_each_camera_has_its_own_gate() -> None:
    """cam-b's rays miss their people by about 0.25 m (its pose is off), cam-a's and cam-c's meet. With one narrow
    gate for all, cam-b's blobs join nobody; with a wide gate for cam-b alone they join, and cam-a's and cam-c's
    still pair within their own narrow gate."""
    parts = [_rays("cam-a", PEOPLE), _rays("cam-b", PEOPLE), _rays("cam-c", PEOPLE)]
    cams, poses = [p[0] for p in parts], [p[1] for p in parts]
    poses[1] = poses[1].moved([0.0, 0.0, 0.0, 0.0, 0.0, 0.25])  # cam-b's centre 0.25 m too high
    r = world_rays(cams, poses)
    narrow = associate(r, 0.1, HeightPrior(), 100.0)
    assert 1 not in narrow.member_camera.tolist() and narrow.person.shape[0] == 3
    own = associate(r, np.array([0.1, 0.4, 0.1]), HeightPrior(), 100.0)
    assert own.person.shape[0] == 3
    for pid in range(3):
        assert sorted(own.member_camera[own.member_person == pid].tolist()) == [0, 1, 2]


def test_candidates_worked_out_together_take_the_people_one_at_a_time_would(monkeypatch: pytest.MonkeyPatch) -> None:
    """A crowd where many candidate pairs share blobs (people 0.3-0.6 m apart, a wide gate, ghosts of crossing rays):
    the pairs whose distances are worked out a block at a time are taken exactly as one by one."""
    import panostereo.calib.associate as assoc

    rng = np.random.default_rng(5)
    crowd = np.column_stack([rng.uniform(2.0, 9.0, 24), rng.uniform(2.0, 8.0, 24), rng.uniform(1.55, 1.9, 24)])
    crowd[1::2, :2] = crowd[::2, :2] + rng.uniform(0.3, 0.6, (12, 2))  # half the people beside another
    parts = [_rays(cid, crowd) for cid in ("cam-a", "cam-b", "cam-c")]
    r = world_rays([p[0] for p in parts], [p[1] for p in parts])
    together = associate(r, 0.6, HeightPrior(), 100.0)
    monkeypatch.setattr(assoc, "GROWTH_BLOCK", 1)
    alone = associate(r, 0.6, HeightPrior(), 100.0)
    assert together.person.shape[0] >= 12
    for field in ("person", "member_person", "member_camera", "member_index"):
        assert np.array_equal(getattr(together, field), getattr(alone, field))


def test_feet_rays_that_pass_far_apart_are_left_out_and_no_pair_that_fits_is() -> None:
    """Rays of two cameras towards points within each gate of one person's feet are always kept (a pair that can
    pass the gates is never left out before it is solved); rays towards feet metres apart are left out."""
    from panostereo.calib.associate import _feet_lines_within

    rng = np.random.default_rng(3)
    parts = [_rays("cam-a", PEOPLE), _rays("cam-c", PEOPLE)]
    r = world_rays([p[0] for p in parts], [p[1] for p in parts])
    centres = r.centre[[0, 3]]
    k = 2000
    feet = np.column_stack([rng.uniform(0.0, 10.0, (k, 2)), np.zeros(k)])
    gate = rng.uniform(0.02, 0.6, (k, 2))

    def towards(c: np.ndarray, p: np.ndarray, off: np.ndarray) -> np.ndarray:
        d = p + off - c
        return d / np.linalg.norm(d, axis=1, keepdims=True)

    def offsets(g: np.ndarray) -> np.ndarray:
        u = rng.normal(size=(k, 3))
        return u / np.linalg.norm(u, axis=1, keepdims=True) * (g * rng.uniform(0.0, 1.0, k))[:, None]

    def pairs(fa: np.ndarray, fb: np.ndarray) -> tuple[object, np.ndarray, np.ndarray]:
        rays = r.take(np.zeros(2 * k, dtype=np.int64))  # copies, to write the pairs' rays into
        rays.centre[:k], rays.centre[k:] = centres[0], centres[1]
        rays.foot[:k], rays.foot[k:] = fa, fb
        return rays, np.arange(k), np.arange(k, 2 * k)

    fit, a, b = pairs(towards(centres[0], feet, offsets(gate[:, 0])), towards(centres[1], feet, offsets(gate[:, 1])))
    assert _feet_lines_within(fit, a, b, gate.sum(axis=1)).all()
    far = feet + np.column_stack([np.full(k, 3.0), np.zeros(k), np.zeros(k)])
    apart, a, b = pairs(towards(centres[0], feet, 0.0 * feet), towards(centres[1], far, 0.0 * feet))
    assert _feet_lines_within(apart, a, b, np.full(k, 0.2)).mean() < 0.05


def test_each_persons_distances_to_every_blob_are_the_pairwise_ones() -> None:
    """The block's distances, every blob from each person at once, equal those worked out blob by blob (feet rays,
    head rays and a pinhole box's head plane alike)."""
    from panostereo.calib.associate import _distances, _distances_each

    parts = [_rays(cid, PEOPLE) for cid in ("cam-a", "cam-b", "cam-c")]
    r = world_rays([p[0] for p in parts], [p[1] for p in parts])
    plane = r.head_plane.copy()
    plane[::2] = np.cross(r.head[::2], [0.0, 0.0, 1.0])  # half the blobs carry a head plane
    plane[::2] /= np.linalg.norm(plane[::2], axis=1, keepdims=True)
    feet_ok = np.arange(r.camera.size) % 3 != 0
    r = dataclasses.replace(r, head_plane=plane, feet_ok=feet_ok)
    persons = PEOPLE + np.array([0.2, -0.1, 0.05])
    n = r.camera.size
    d, front = _distances_each(r, persons)
    d1, front1 = _distances(r, np.tile(np.arange(n), len(persons)), np.repeat(persons, n, axis=0))
    np.testing.assert_allclose(d, d1.reshape(len(persons), n), rtol=1e-12, atol=1e-12)
    assert np.array_equal(front, front1.reshape(len(persons), n))
