"""A synthetic dataset site for the calibration tests: pinhole cameras around a square, people walking between
random waypoints, each camera's boxes projected from them (feet to head top), and the site written by the
importer's own templates. The site's calibrations can be a perturbed copy of the true ones (the starting guess)."""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from common.pinhole import PinholeCamera, rotation_from_rvec
from panostereo.datasets.mot import write_site
from tests.unit.panostereo.mot_synth import SIZE, K

CAMERAS = {
    "cam-a": (-2.0, -2.0, 3.0),
    "cam-b": (14.0, -2.0, 3.2),
    "cam-c": (14.0, 14.0, 2.8),
    "cam-d": (-2.0, 14.0, 3.0),
}
"""Camera id -> (x, y, height) of its optical centre; each looks at the square's middle (6, 6)."""
SQUARE_M = (1.0, 11.0)
"""People walk within this range of x and of y."""


def look_at(x: float, y: float, z: float, target: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """(R, t) of a camera at (x, y, z) looking at ``target`` on the floor (world -> camera)."""
    c = np.array([x, y, z])
    fwd = np.array([target[0], target[1], 0.0]) - c
    fwd /= np.linalg.norm(fwd)
    right = np.cross(fwd, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    r = np.array([right, np.cross(fwd, right), fwd])
    return r, -r @ c


def true_cameras(away: set[str] | None = None) -> dict[str, PinholeCamera]:
    """The true cameras; those in ``away`` look out of the square (they see nobody)."""
    out = {}
    for cid, (x, y, z) in CAMERAS.items():
        target = (2 * x - 6.0, 2 * y - 6.0) if away and cid in away else (6.0, 6.0)
        r, t = look_at(x, y, z, target)
        out[cid] = PinholeCamera(k=np.array(K), dist=np.zeros(5), r=r, t=t, width_px=SIZE[0], height_px=SIZE[1])
    return out


def bumped(cam: PinholeCamera, shift_m: float, turn_rad: float, rng: np.random.Generator) -> PinholeCamera:
    """The camera moved by ``shift_m`` in a random direction and turned by ``turn_rad`` about a random axis."""
    d = rng.normal(size=3)
    a = rng.normal(size=3)
    centre = cam.center_world + shift_m * d / np.linalg.norm(d)
    r = cam.r @ rotation_from_rvec(turn_rad * a / np.linalg.norm(a)).T
    return PinholeCamera(k=cam.k, dist=cam.dist, r=r, t=-r @ centre, width_px=cam.width_px, height_px=cam.height_px)


def walkers(people: int, frames: int, fps: float, rng: np.random.Generator) -> np.ndarray:
    """(frames, people, 3): x, y and head height of people walking at 1.2 m/s between random waypoints."""
    lo, hi = SQUARE_M
    pos = rng.uniform(lo, hi, size=(people, 2))
    goal = rng.uniform(lo, hi, size=(people, 2))
    height = rng.uniform(1.6, 1.9, size=people)
    out = np.empty((frames, people, 3))
    step = 1.2 / fps
    for k in range(frames):
        out[k, :, :2] = pos
        out[k, :, 2] = height
        d = goal - pos
        dist = np.linalg.norm(d, axis=1)
        arrived = dist < step
        goal[arrived] = rng.uniform(lo, hi, size=(int(arrived.sum()), 2))
        pos = np.where(arrived[:, None], pos, pos + d / np.maximum(dist, 1e-9)[:, None] * step)
    return out


def _box(cam: PinholeCamera, x: float, y: float, h: float, noise: np.ndarray) -> tuple[float, ...] | None:
    """The box of a person at (x, y) with head height h, or None out of the picture."""
    c = cam.center_world
    d = math.hypot(x - c[0], y - c[1])
    side = np.array([-(y - c[1]), x - c[0]]) / d * 0.22
    pts = np.array([[x + side[0], y + side[1], 0.0], [x - side[0], y - side[1], 0.0], [x, y, 0.0], [x, y, h]])
    uv, front = cam.project(pts)
    if not front.all():
        return None
    left, right = float(min(uv[:2, 0])), float(max(uv[:2, 0]))
    top, bottom = float(uv[3, 1]), float(uv[2, 1])
    left, right, top, bottom = left + noise[0], right + noise[1], top + noise[2], bottom + noise[3]
    if left < 1 or right > SIZE[0] - 1 or top < 1 or bottom > SIZE[1] - 1 or bottom - top < 10:
        return None
    return left, top, right - left, bottom - top


def write_site_dir(
    root: Path,
    start: Mapping[str, PinholeCamera],
    truth: Mapping[str, PinholeCamera],
    *,
    people: int = 6,
    frames: int = 60,
    fps: float = 2.0,
    noise_px: float = 1.0,
    clutter_per_frame: int = 0,
    companion_m: float = 0.0,
    seed: int = 0,
) -> Path:
    """A dataset site under ``root``: boxes from the ``truth`` cameras, calibrations from ``start``; ``clutter``:
    random boxes where nobody is, in every camera; ``companion_m`` > 0: everyone walks with a companion this far
    beside them (on their left), 0.2 m taller or shorter (twice the people). Returns the site file."""
    rng = np.random.default_rng(seed)
    (root / "calib").mkdir(parents=True, exist_ok=True)
    (root / "detections").mkdir(parents=True, exist_ok=True)
    paths = walkers(people, frames, fps, rng)
    if companion_m > 0:  # side by side: to the left of where each is heading
        heading = np.diff(paths[:, :, :2], axis=0, append=paths[-1:, :, :2] + (paths[-1:, :, :2] - paths[-2:-1, :, :2]))
        left = np.stack([-heading[..., 1], heading[..., 0]], axis=-1)
        left /= np.maximum(np.linalg.norm(left, axis=-1, keepdims=True), 1e-9)
        beside = paths.copy()
        beside[:, :, :2] += companion_m * left
        beside[:, :, 2] += np.where(paths[0, :, 2] > 1.75, -0.2, 0.2)
        paths = np.concatenate([paths, beside], axis=1)
        people *= 2
    gt = ["frame,id,x_m,y_m"]
    for k in range(frames):
        gt += [f"{k + 1},{p + 1},{paths[k, p, 0]:.3f},{paths[k, p, 1]:.3f}" for p in range(people)]
    for cid, cam in truth.items():
        s = start[cid]
        calib = {"model": "pinhole", "image_size": list(SIZE), "K": K, "dist": [0.0] * 5, "R": s.r.tolist()}
        calib["t"] = s.t.tolist()
        (root / "calib" / f"{cid}.json").write_text(json.dumps(calib))
        rows = []
        for k in range(frames):
            for p in range(people):
                box = _box(cam, *paths[k, p], rng.normal(0.0, noise_px, size=4))
                if box is not None:
                    rows.append(f"{k + 1},-1,{box[0]:.2f},{box[1]:.2f},{box[2]:.2f},{box[3]:.2f},0.9,-1,-1,-1")
            for _ in range(clutter_per_frame):
                u, v = rng.uniform(50, SIZE[0] - 100), rng.uniform(50, SIZE[1] - 250)
                rows.append(f"{k + 1},-1,{u:.1f},{v:.1f},40.0,120.0,0.9,-1,-1,-1")
        if not rows:  # a detection file must hold a box: one far off, alone
            rows.append("1,-1,10.0,10.0,5.0,12.0,0.9,-1,-1,-1")
        (root / "detections" / f"{cid}.txt").write_text("\n".join(rows) + "\n")
    (root / "gt.csv").write_text("\n".join(gt) + "\n")
    return write_site(root, name="synth", cameras=list(truth), fps=fps, frames=frames, has_gt=True)


PANORAMAS = {"pano1": (1.0, 1.0, 1.1, 0.0), "pano2": (11.0, 1.5, 1.2, 2.0), "pano3": (6.0, 11.0, 1.15, -1.5)}
"""Panoramic camera id -> (x, y, height, yaw rad) of a static camera on a post."""


def write_panoramic_recording(
    root: Path, start: Mapping[str, tuple[float, float, float, float]], *, seconds: float = 20.0, fps: float = 10.0
) -> tuple[Path, Path]:
    """A live site of the panoramic cameras (node configs with a ``[pose]`` from ``start``) and a recording of it:
    every camera's SensorInfo (its ``start`` pose) and Features whose blobs the true cameras (``PANORAMAS``) saw,
    stamps jittered as a live network's are. Returns (site file, recording)."""
    from common.codec import encode
    from common.keys import Keys
    from common.schema import Blob, Features, PanoramicModel, Pose, SensorInfo
    from user_agent.record import McapSink

    keys = Keys("pano")
    epoch = 1_700_000_000_000_000_000
    rng = np.random.default_rng(4)
    frames = int(seconds * fps)
    paths = walkers(5, frames, fps, rng)
    (root / "nodes").mkdir(parents=True, exist_ok=True)
    procs = []
    for sid, (x, y, z, yaw) in start.items():
        (root / "nodes" / f"{sid}.toml").write_text(
            f'[node]\nid = "{sid}"\n\n[source]\nkind = "sim"\nsite = "../site.toml"\ncamera = "{sid}"\n\n'
            f"[pose]    # surveyed\nx_m = {x}\ny_m = {y}\nz_m = {z}\nyaw_deg = {math.degrees(yaw)}\n"
        )
        procs.append(f'[[process]]\nname = "{sid}"\ncommand = "node"\nconfig = "nodes/{sid}.toml"\n')
    site = root / "site.toml"
    site.write_text('[site]\nname = "panos"\n\n' + "\n".join(procs))
    sink = McapSink(root / "rec.mcap")
    model = PanoramicModel(width_px=1080, height_px=162, f_v_px=256.0, v0_px=93.0)
    for sid, (x, y, z, yaw) in start.items():
        pose = Pose(x_m=x, y_m=y, z_m=z, yaw_rad=yaw)
        info = SensorInfo(
            sensor_id=sid, seq=0, stamp_ns=epoch, kind="panoramic", model=model, pose=pose, pose_source="surveyed"
        )
        sink.write(keys.sensor_info(sid), encode(info), epoch)
    for k in range(frames):
        for sid, (x, y, z, yaw) in PANORAMAS.items():
            blobs = []
            for p, (px, py, h) in enumerate(paths[k]):
                rho = math.hypot(px - x, py - y)
                bearing = math.remainder(math.atan2(py - y, px - x) - yaw + rng.normal(0.0, 0.003), 2 * math.pi)
                top = math.atan2(h - z, rho) + rng.normal(0.0, 0.003)
                bottom = math.atan2(-z, rho) + rng.normal(0.0, 0.003)
                blobs.append(
                    Blob(local_id=p, bearing_rad=bearing, width_rad=0.45 / rho, top_elev_rad=top,
                         bottom_elev_rad=bottom, bbox_u_px=0.0, bbox_v_px=10.0, bbox_w_px=10.0, bbox_h_px=50.0)
                )  # fmt: skip
            stamp = epoch + int(k / fps * 1e9) + int(rng.integers(0, 3_000_000))
            f = Features(sensor_id=sid, seq=k, stamp_ns=stamp, frame_index=k, blobs=blobs)
            sink.write(keys.sensor_features(sid), encode(f), stamp + 5_000_000)
    sink.close()
    return site, root / "rec.mcap"
