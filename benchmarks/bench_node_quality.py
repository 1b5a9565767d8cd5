"""Sensor-node blob quality on rendered frames: head bearings, merges, detections, false blobs.

Usage::

    python -m benchmarks.bench_node_quality [--site deploy/sites/six.toml ...] [--duration 12] [--t0 4]
                                            [--score-every 3] [--camera cam1 ...] [--world-seed 5]

For each panoramic camera of each site, renders frames with the simulator
(:class:`sim.render.cameras.PanoramicRenderer`; people walking, lighting,
sensor noise) from world time ``t0 - warmup`` on, runs every frame through
:class:`sensor_node.pipeline.ImagePipeline` exactly as a node does (default
``[pipeline]`` settings, the other cameras as known bodies), and scores every
``score-every``-th frame from ``t0`` on against the ground truth projected
into that camera. Ground truth -- the world's people and the renderer's label
image -- is used only here, to score; the pipeline sees the pixels only.

Per visible person (head at least ``HEAD_VISIBLE`` of its unoccluded pixels
in view) and frame:

* **detected** -- a blob's head bearing lies on the person's silhouette
  columns (one blob per person, Hungarian on the bearing error);
* **head bearing error** -- blob bearing minus the true bearing of the
  person's position (the head centre): median |e|, p90 |e|, bias (mean e),
  in degrees and panorama pixels; also for *isolated* people only (no other
  silhouette within ``ISOLATED_GAP_PX`` columns, head fully visible), which
  separates the head estimate from the effects of merging;
* **merged** -- the person's head column lies in the box of a blob that also
  holds another visible person's head column; *separable* merges are those
  with someone whose silhouette does not even touch theirs (a split should
  have parted them); *heads-apart* merges are those with someone whose
  head columns do not overlap theirs (a cut between the heads could part
  them, whatever the bodies do); all as fractions of the visible person-frames;
* **cut heads** -- people so close that their head is above the panorama
  (isolated): bearing error of the nearest blob on them (their "head" is
  their neck or shoulders), scored apart;
* **low-confidence head error** -- the head bearing error of the detections
  whose blob has ``confidence`` < 1 (the node lowers it when the blob
  reaches the panorama's top row: the head may be cut);
* **top error** -- blob top elevation minus the true head-top elevation (rows);
  **width error** -- blob angular width / silhouette width - 1 (isolated);
* **false blobs** -- blobs that touch no person's silhouette columns;
  **extra blobs** -- a second blob whose head bearing lies on a visible
  person's silhouette (over-splitting, or a ghost in front of them), unless
  it lies on the head columns of someone partly hidden behind them (less
  than ``HEAD_VISIBLE`` of the head in view): those are counted apart as
  **blobs on hidden heads**.

Prints one JSON object: per site (all its cameras pooled) and per camera.
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import os
import sys
import time
import tomllib
from pathlib import Path
from typing import Any

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import cv2
import msgspec
import numpy as np
from scipy.optimize import linear_sum_assignment

from common.schema import Blob
from common.site import CameraSpec, SiteConfig, load_site
from sensor_node.config import BodySpec, PipelineSettings
from sensor_node.features import PanoramicGeometry
from sensor_node.pipeline import ImagePipeline
from sensor_node.unwarp import Unwarper
from sim.render.bodies import head_size
from sim.render.cameras import PANO_MARGIN_ROWS, PanoramicRenderer
from sim.world import World, sensor_bearing, site_with_seed

logger = logging.getLogger(__name__)
REPO = Path(__file__).resolve().parent.parent
SITES = ("six", "paper1", "demo")

HEAD_VISIBLE = 0.6
"""A person counts as visible when this fraction of their unoccluded head pixels is in the label image."""

ISOLATED_GAP_PX = 6
"""Columns between a person's silhouette and anyone else's for the person to count as isolated."""

ON_BODY_MARGIN_PX = 2.0
"""A blob's head bearing may lie this far outside the silhouette's columns and still detect the person."""


def _on_body(blob_u: Any, q: dict[str, Any], width: float) -> tuple[Any, Any]:
    """Each blob's column offset from person ``q``'s head, and whether it lies on their silhouette's columns."""
    e = _wrap(blob_u - q["u"], width)
    return e, (e >= q["lo"] - ON_BODY_MARGIN_PX) & (e <= q["hi"] + ON_BODY_MARGIN_PX)


def _wrap(x: np.ndarray | float, width: float) -> Any:
    """Column differences wrapped to [-W/2, W/2)."""
    return (np.asarray(x) + width / 2.0) % width - width / 2.0


def _describe(b: Any, head_u: float) -> str:
    """A blob's box and head column, for debug logs."""
    return f"box u={b.bbox_u_px:.0f} v={b.bbox_v_px:.0f} w={b.bbox_w_px:.0f} h={b.bbox_h_px:.0f} head u={head_u:.1f}"


class _Scores:
    """Accumulated per-camera (or pooled) figures."""

    def __init__(self) -> None:
        self.visible = 0
        self.detected = 0
        self.merged = 0
        self.separable_merged = 0
        self.heads_apart_merged = 0
        self.frames = 0
        self.blobs = 0
        self.false_blobs = 0
        self.extra = 0
        self.hidden_heads = 0
        self.err_px: list[float] = []
        self.err_iso_px: list[float] = []
        self.err_cut_px: list[float] = []
        self.err_low_conf_px: list[float] = []
        self.top_px: list[float] = []
        self.width_rel: list[float] = []

    def add(self, other: _Scores) -> None:
        for k, v in vars(other).items():
            if isinstance(v, list):
                getattr(self, k).extend(v)
            else:
                setattr(self, k, getattr(self, k) + v)

    def summary(self, f_h_px: float) -> dict[str, Any]:
        def stats(xs: list[float], deg: bool) -> dict[str, Any]:
            if not xs:
                return {"n": 0}
            a = np.asarray(xs)
            k = math.degrees(1.0 / f_h_px) if deg else 1.0
            return {
                "n": int(a.size),
                "median_abs": round(float(np.median(np.abs(a))) * k, 4),
                "p90_abs": round(float(np.percentile(np.abs(a), 90)) * k, 4),
                "bias": round(float(np.mean(a)) * k, 4),
            }

        return {
            "frames_scored": self.frames,
            "person_frames_visible": self.visible,
            "detection_rate": round(self.detected / max(self.visible, 1), 4),
            "merge_rate": round(self.merged / max(self.visible, 1), 4),
            "separable_merge_rate": round(self.separable_merged / max(self.visible, 1), 4),
            "heads_apart_merge_rate": round(self.heads_apart_merged / max(self.visible, 1), 4),
            "blobs_per_frame": round(self.blobs / max(self.frames, 1), 3),
            "false_blobs_per_frame": round(self.false_blobs / max(self.frames, 1), 4),
            "extra_blobs_on_people_per_frame": round(self.extra / max(self.frames, 1), 4),
            "blobs_on_hidden_heads_per_frame": round(self.hidden_heads / max(self.frames, 1), 4),
            "head_bearing_err_deg": stats(self.err_px, True),
            "head_bearing_err_px": stats(self.err_px, False),
            "isolated_head_bearing_err_deg": stats(self.err_iso_px, True),
            "isolated_head_bearing_err_px": stats(self.err_iso_px, False),
            "cut_head_bearing_err_px": stats(self.err_cut_px, False),
            "low_confidence_head_bearing_err_px": stats(self.err_low_conf_px, False),
            "top_err_rows": stats(self.top_px, False),
            "isolated_width_rel_err": stats(self.width_rel, False),
        }


def _bodies(site: SiteConfig, camera: str) -> list[BodySpec]:
    return [
        BodySpec(id=c.id, band_rgb=list(c.band_rgb), radius_m=c.body_radius_m, height_m=c.body_height_m)
        for c in site.camera
        if c.id != camera and c.body_radius_m > 0
    ]


def _score_frame(
    sc: _Scores, world: World, cam: CameraSpec, renderer: PanoramicRenderer, t_s: float, blobs: list[Blob]
) -> None:
    cyl = renderer.models[1]
    width = float(cyl.width_px)
    _, labels = renderer.render_panorama(t_s, with_labels=True)
    assert labels is not None
    m = PANO_MARGIN_ROWS
    labels = labels[m:-m]
    me = world.platform_at(cam.id, t_s)
    people = [p for p in world.people_at(t_s) if p.present]
    sc.frames += 1
    sc.blobs += len(blobs)
    col_ids = [
        np.flatnonzero(((labels == 2 * p.person_id) | (labels == 2 * p.person_id + 1)).any(axis=0)) for p in people
    ]
    head_px = [int(np.count_nonzero(labels == 2 * p.person_id)) for p in people]
    head_cols = [np.flatnonzero((labels == 2 * p.person_id).any(axis=0)) for p in people]
    blob_u = np.asarray([float(cyl.col_from_bearing(b.bearing_rad)) for b in blobs])
    persons: list[dict[str, Any]] = []
    for p, pc, hp, hc in zip(people, col_ids, head_px, head_cols, strict=True):
        if pc.size == 0:
            continue
        d = math.dist((p.x_m, p.y_m), (me.x_m, me.y_m))
        rh, rv = head_size(p.height_m)
        expected = math.pi * (math.asin(min(1.0, rh / d)) * cyl.f_h_px) * (rv * cyl.f_v_px / d)
        b = sensor_bearing(me, p.x_m, p.y_m)
        u = float(cyl.col_from_bearing(b))
        off = _wrap(pc - u, width)
        lo, hi = float(off.min()) - 0.5, float(off.max()) + 0.5
        top_elev = math.atan((p.height_m - me.z_m) / d)
        persons.append(
            {
                "u": u,
                "lo": lo,
                "hi": hi,
                "vis": hp / max(expected, 1.0),
                "top_v": float(cyl.row_from_elevation(top_elev)),
                "head_cols": set(hc.tolist()),
            }
        )
    visible = [q for q in persons if q["vis"] >= HEAD_VISIBLE]
    # Silhouette spans in absolute (unwrapped around each person's own head) columns, for isolation tests.
    for q in persons:
        q["a"], q["b"] = q["u"] + q["lo"], q["u"] + q["hi"]

    def gap(q1: dict[str, Any], q2: dict[str, Any]) -> float:
        shift = float(_wrap(q2["u"] - q1["u"], width)) - (q2["u"] - q1["u"])
        a2, b2 = q2["a"] + shift, q2["b"] + shift
        return max(a2 - q1["b"], q1["a"] - b2)

    n_b = len(blobs)
    box_lo = np.asarray([b.bbox_u_px - 0.5 for b in blobs])
    box_w = np.asarray([b.bbox_w_px for b in blobs])

    def in_box(u: float) -> np.ndarray:
        return _wrap(u - box_lo, width) % width <= box_w if n_b else np.zeros(0, bool)

    sc.visible += len(visible)
    holds = [in_box(q["u"]) for q in visible]
    for i, q in enumerate(visible):
        others = [j for j in range(len(visible)) if j != i and (holds[i] & holds[j]).any()]
        if others:
            sc.merged += 1
        if any(not (q["head_cols"] & visible[j]["head_cols"]) for j in others):
            sc.heads_apart_merged += 1
            logger.debug(
                "%s t=%.2f heads-apart merge: person at u=%.1f [%.1f, %.1f] with %s",
                cam.id,
                t_s,
                q["u"],
                q["a"],
                q["b"],
                [round(visible[j]["u"], 1) for j in others if not (q["head_cols"] & visible[j]["head_cols"])],
            )
        if any(gap(q, visible[j]) > 0 for j in others):
            sc.separable_merged += 1
            logger.debug(
                "%s t=%.2f separable merge: person at u=%.1f [%.1f, %.1f] with %s; blobs %s",
                cam.id,
                t_s,
                q["u"],
                q["a"],
                q["b"],
                [(round(visible[j]["u"], 1), round(visible[j]["a"], 1), round(visible[j]["b"], 1)) for j in others],
                [(b.bbox_u_px, b.bbox_w_px, round(float(u), 1)) for b, u in zip(blobs, blob_u, strict=True)],
            )
    # People too close to have their head in view (cut by the panorama's top), clear of everyone else:
    # the nearest blob bearing on their silhouette (the blob's top is their neck or shoulders).
    for q in persons:
        if q["vis"] >= HEAD_VISIBLE or q["top_v"] >= 0.0 or n_b == 0:
            continue
        if any(gap(q, q2) <= ISOLATED_GAP_PX for q2 in persons if q2 is not q):
            continue
        e, ok = _on_body(blob_u, q, width)
        if ok.any():
            sc.err_cut_px.append(float(e[ok][np.argmin(np.abs(e[ok]))]))
    # Assignment: a blob's head bearing on the person's silhouette columns; min total |error|.
    if visible and n_b:
        cost = np.full((len(visible), n_b), 1e6)
        for i, q in enumerate(visible):
            e, ok = _on_body(blob_u, q, width)
            cost[i, ok] = np.abs(e[ok])
        rows, cols_a = linear_sum_assignment(cost)
        matched = [(int(i), int(j)) for i, j in zip(rows, cols_a, strict=True) if cost[i, j] < 1e6]
        assigned = {j for _, j in matched}
        # A second blob on one person (over-splitting: an arm or a shoulder parted from the body).
        extra = [j for j in range(n_b) if j not in assigned and bool((cost[:, j] < 1e6).any())]
        # A blob on the head of someone partly hidden behind a visible person (less than HEAD_VISIBLE of
        # their head in view: not scored as a detection) is that person, not an over-split.
        hidden = [q["head_cols"] for q in persons if q["vis"] < HEAD_VISIBLE]
        on_hidden = [j for j in extra if any(round(float(blob_u[j])) % round(width) in hc for hc in hidden)]
        sc.hidden_heads += len(on_hidden)
        extra = [j for j in extra if j not in on_hidden]
        sc.extra += len(extra)
        for j in extra:
            b = blobs[j]
            logger.debug(
                "%s t=%.2f extra blob: %s; people %s",
                cam.id,
                t_s,
                _describe(b, blob_u[j]),
                [(round(q["u"], 1), round(q["a"], 1), round(q["b"], 1)) for q in visible],
            )
        found = {i for i, _ in matched}
        for i, q in enumerate(visible):
            if i not in found:
                logger.debug("%s t=%.2f missed: person at u=%.1f [%.1f, %.1f]", cam.id, t_s, q["u"], q["a"], q["b"])
        for i, j in matched:
            q = visible[i]
            sc.detected += 1
            e = float(_wrap(blob_u[j] - q["u"], width))
            sc.err_px.append(e)
            if blobs[j].confidence < 1.0:
                sc.err_low_conf_px.append(e)
            iso = q["vis"] >= 0.9 and all(gap(q, q2) > ISOLATED_GAP_PX for q2 in persons if q2 is not q)
            if iso:
                sc.err_iso_px.append(e)
                sw = (q["hi"] - q["lo"]) / cyl.f_h_px
                sc.width_rel.append(blobs[j].width_rad / sw - 1.0)
            top_v = float(cyl.row_from_elevation(blobs[j].top_elev_rad))
            if top_v > 0.5:  # a head cut by the panorama's top edge has no top to score
                sc.top_px.append(top_v - q["top_v"])
    # False blobs: touch no present person's silhouette.
    for j in range(n_b):
        touches = False
        for q in persons:
            a = float(_wrap(box_lo[j] - q["u"], width))
            if a - 1.0 <= q["hi"] and q["lo"] <= a + box_w[j] + 1.0:
                touches = True
                break
        if not touches:
            sc.false_blobs += 1
            logger.debug("%s t=%.2f false blob: %s", cam.id, t_s, _describe(blobs[j], blob_u[j]))


def run_camera(
    site: SiteConfig,
    cam: CameraSpec,
    settings: PipelineSettings,
    t0_s: float,
    duration_s: float,
    warmup_s: float,
    every: int,
    seed: int,
) -> tuple[_Scores, float, dict[str, float]]:
    """Score one camera; returns its scores, its f_h (px/rad) and timing."""
    world = World.from_site(site)
    renderer = PanoramicRenderer(world, cam)
    annular, cyl = renderer.models
    pipe = ImagePipeline(
        cam.id, PanoramicGeometry(cyl), settings, Unwarper(annular), _bodies(site, cam.id), mobile=cam.mobile
    )
    rng = np.random.default_rng(seed)
    fps = site.site.fps
    k0 = round((t0_s - warmup_s) * fps)
    n = round((warmup_s + duration_s) * fps)
    sc = _Scores()
    t_proc = 0.0
    for k in range(k0, k0 + n):
        t = k / fps
        frame = renderer.render(t, rng)
        c0 = time.thread_time()
        res = pipe.process(frame, stamp_ns=round(t * 1e9), frame_index=k)
        t_proc += time.thread_time() - c0
        if t < t0_s or (k - k0) % every or res.state != "ok":
            continue
        _score_frame(sc, world, cam, renderer, t, list(res.features.blobs))
    return sc, cyl.f_h_px, {"pipeline_ms_per_frame": round(t_proc / n * 1e3, 3)}


def _with_extras(site: SiteConfig, shadow_gain: float | None, sway_m: float | None) -> SiteConfig:
    """The site with its lighting's cast shadows and swaying distractor set (None: the site's own)."""
    lit = site.world.lighting
    if shadow_gain is not None:
        lit = msgspec.structs.replace(lit, shadow_gain=shadow_gain)
    if sway_m is not None:
        lit = msgspec.structs.replace(lit, sway_m=sway_m)
    return msgspec.structs.replace(site, world=msgspec.structs.replace(site.world, lighting=lit))


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--site", action="append", help="site file (repeatable; default: six, paper1, demo)")
    p.add_argument("--camera", action="append", help="only these camera ids")
    p.add_argument("--duration", type=float, default=12.0, help="scored seconds per camera")
    p.add_argument("--t0", type=float, default=4.0, help="world time of the first scored frame (s)")
    p.add_argument("--warmup", type=float, default=3.0, help="unscored seconds before t0 (background learning)")
    p.add_argument("--score-every", type=int, default=3)
    p.add_argument("--seed", type=int, default=1, help="sensor-noise seed")
    p.add_argument(
        "--world-seed",
        type=int,
        default=None,
        help="world seed (people, paths, looks) instead of each site's own, as `panostereo demo --seed`",
    )
    p.add_argument(
        "--set", action="append", default=[], metavar="KEY=TOML", help="[pipeline] override, e.g. split_dip_px=6"
    )
    p.add_argument("--shadow-gain", type=float, default=None, help="[world.lighting] shadow_gain for every site")
    p.add_argument("--sway-m", type=float, default=None, help="[world.lighting] sway_m for every site")
    p.add_argument("-v", "--verbose", action="store_true", help="log merges, extra and false blobs, misses (stderr)")
    args = p.parse_args(argv)
    logging.basicConfig(level=logging.DEBUG if args.verbose else logging.WARNING, format="%(message)s")
    for name in ("sensor_node", "common"):
        logging.getLogger(name).setLevel(logging.WARNING)
    overrides = {k: tomllib.loads(f"v = {v}")["v"] for k, v in (kv.split("=", 1) for kv in args.set)}
    settings = msgspec.convert(overrides, PipelineSettings)
    cv2.setNumThreads(1)
    sites = args.site or [str(REPO / "deploy" / "sites" / f"{s}.toml") for s in SITES]
    result: dict[str, Any] = {"benchmark": "sensor_node.quality", "settings": vars(args) | {"site": sites}}
    t_start = time.perf_counter()
    for path in sites:
        site = _with_extras(site_with_seed(load_site(Path(path)), args.world_seed), args.shadow_gain, args.sway_m)
        pooled = _Scores()
        per_cam: dict[str, Any] = {}
        f_h = 1.0
        for cam in site.camera:
            if cam.kind != "panoramic" or (args.camera and cam.id not in args.camera):
                continue
            sc, f_h, timing = run_camera(
                site, cam, settings, args.t0, args.duration, args.warmup, args.score_every, args.seed
            )
            per_cam[cam.id] = sc.summary(f_h) | timing
            pooled.add(sc)
        result[site.site.name] = {"world_seed": site.site.seed, "all": pooled.summary(f_h), "cameras": per_cam}
    result["wall_s"] = round(time.perf_counter() - t_start, 1)
    json.dump(result, sys.stdout, indent=2)
    sys.stdout.write("\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
