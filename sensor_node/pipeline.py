"""The image pipeline of one camera: frame in, Features out (pure: no zenoh, no clock).

Panoramic cameras: annular frame -> unwarp -> grey -> background model ->
blobs -> split at head valleys -> split between the 2D tracks' predicted heads -> (robot bodies
removed) -> head + annotation -> 2D tracks -> Features,
with the sightings of other robots (Eq. 3) every ``sighting_every`` frames.
Perspective (PTZ) cameras skip the unwarp and the sightings and report world
azimuths; the background model restarts whenever the head moves.

Performance: the background model works on one grey channel at panorama
resolution; colour (histograms, band search) is used only inside blob boxes
and below the horizon; the background update runs every ``update_every``
frames. ``benchmarks/bench_pipeline.py`` measures it against an OpenCV floor.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt

from common.errors import SourceError
from common.schema import DetectorState, Features
from sensor_node.background.model import BackgroundModel, Motion, MotionState
from sensor_node.config import BodySpec, PipelineSettings
from sensor_node.features import ImageGeometry, PanoramicGeometry, PinholeGeometry, annotate, to_wire
from sensor_node.segmentation.blobs import find_blobs
from sensor_node.segmentation.groups import split_by_tracks
from sensor_node.segmentation.head_splits import split_at_heads
from sensor_node.sightings import BandFinder, BodySighting, is_body_blob
from sensor_node.tracks2d import Tracker2D
from sensor_node.unwarp import PanoFrame, Unwarper

__all__ = ["FrameResult", "ImagePipeline"]

Image = npt.NDArray[Any]
Mask = npt.NDArray[Any]

DETECTOR_STATE: dict[MotionState, DetectorState] = {
    "ok": "ok",
    "relit": "ok",
    "warmup": "learning",
    "reinit": "learning",
    "moving": "moving",
}
"""What an empty blob list means (``Features.state``): the background model's verdict on the frame. A
relit frame is reported as seen (its objects are just not reported on that one frame); a PTZ head that
slews resets the model, so its frames say "learning" until it is relearnt."""

TRACK_SPLIT_MISSED = 0
"""Frames a 2D track may have gone unseen and still split a blob its predicted head falls in. 0 (seen in
the last frame): on six (``benchmarks/bench_node_quality.py``, seeds 5 and 9) 2 found 0.3-0.6 % more
people but kept cutting the shoulder off a near person who had just hidden someone (extra blobs on
people 0.145 -> 0.21 and 0.185 -> 0.265 per frame)."""


@dataclass(frozen=True, slots=True)
class FrameResult:
    """What one frame produced."""

    features: Features
    state: MotionState
    """The background model's verdict on this frame."""
    body_blobs: int
    """Motion blobs recognised as robot bodies (not reported as people)."""
    frame: PanoFrame
    """The processed frame (grey panorama, reduced colour)."""


def objects_mask(motion: Motion, background: BackgroundModel, floor: Mask | None = None) -> tuple[Mask, Mask]:
    """The changed pixels that may be objects, and the same before the vote.

    Shadows and highlights are removed (:mod:`sensor_node.background.shadows`), then a 3 x 3 majority vote, so
    isolated pixels (compression noise, a frame-difference trail, the edge of something swinging) neither
    chain blobs together nor stretch their boxes, and one-pixel holes close. The vote also erases what is
    thin or sparse in a person (a neck, the outline of a shirt of the wall's grey): grouping joins the
    parts above one another through the mask before it (:func:`sensor_node.segmentation.blobs.find_blobs`).
    """
    fg = motion.fg
    shade = background.shadows(fg, floor)
    if shade is not None:
        fg = cv2.subtract(fg, shade)
    return cv2.medianBlur(fg, 3), fg


def below_horizon(geometry: ImageGeometry, width: int, height: int, scale: int) -> Mask:
    """255 on the pixels of a ``scale``-times reduced image whose ray points below the horizon."""
    if isinstance(geometry, PinholeGeometry):
        vv, uu = np.mgrid[0:height, 0:width].astype(np.float64) * scale
        _, elev = geometry.camera.bearing_elevation(np.column_stack([uu.ravel(), vv.ravel()]))
        below = np.asarray(elev).reshape(height, width) < 0.0
    else:
        rows = np.asarray([geometry.elevation(0.0, float(r * scale)) for r in range(height)]) < 0.0
        below = np.repeat(rows[:, None], width, axis=1)
    return np.where(below, 255, 0).astype(np.uint8)


class ImagePipeline:
    """All stages for one camera.

    Args:
        sensor_id: published in every Features.
        geometry: pixel -> angles of the processed image.
        settings: the ``[pipeline]`` knobs.
        unwarper: annular -> panorama (None: frames are already the processed image).
        bodies: the other robots to look for (panoramic cameras only).
        mobile: the camera rides a robot (the background model watches for its motion).
    """

    def __init__(
        self,
        sensor_id: str,
        geometry: ImageGeometry,
        settings: PipelineSettings,
        unwarper: Unwarper | None = None,
        bodies: list[BodySpec] | None = None,
        *,
        mobile: bool = False,
    ) -> None:
        self.sensor_id = sensor_id
        self.geometry = geometry
        self.settings = settings
        self.unwarper = unwarper
        self.mobile = mobile
        self.background = BackgroundModel(settings, mobile=mobile)
        self.bands = (
            BandFinder(bodies, geometry.camera, settings)
            if bodies and isinstance(geometry, PanoramicGeometry)
            else None
        )
        self._tracker: Tracker2D | None = None
        self._last_sightings: list[BodySighting] = []
        self._frames = 0
        self.seq = 0
        self._floor_key: tuple[int, int, int] | None = None
        self._floor_mask: Mask | None = None

    def _floor(self, pf: PanoFrame) -> Mask | None:
        """255 on the reduced colour image's pixels whose ray points below the horizon (cached per geometry)."""
        if not self.settings.shadows:
            return None
        small = pf.small
        key = (small.shape[0], small.shape[1], id(self.geometry))
        if self._floor_key != key:
            self._floor_mask = below_horizon(self.geometry, small.shape[1], small.shape[0], pf.scale)
            self._floor_key = key
        return self._floor_mask

    def reset(self) -> None:
        """Forget the background and tracks (the camera moved: a PTZ head slewed)."""
        self.background = BackgroundModel(self.settings, fast_start=True, mobile=self.mobile)
        self._tracker = None

    def set_geometry(self, geometry: ImageGeometry) -> None:
        """New pixel -> angle mapping (a PTZ head at a new pose)."""
        self.geometry = geometry

    def process(self, frame: Image, stamp_ns: int, frame_index: int) -> FrameResult:
        """Run every stage on one frame and build its Features (``processing_ms`` left 0)."""
        s = self.settings
        if self.unwarper is None and isinstance(self.geometry, PinholeGeometry):
            cam = self.geometry.camera
            h, w = frame.shape[:2]
            if (w, h) != (cam.width_px, cam.height_px):
                raise SourceError(
                    f"frame is {w}x{h} px but the camera calibration is for {cam.width_px}x{cam.height_px} "
                    "(calibration image_size)"
                )
        pf = self.unwarper.frame(frame) if self.unwarper is not None else PanoFrame.from_image(frame)
        grey = pf.grey
        motion = self.background.apply(grey, stamp_ns, pf.small if s.shadows else None)
        width = grey.shape[1]
        fg, before_vote = (
            objects_mask(motion, self.background, self._floor(pf)) if motion.reportable else (motion.fg, motion.fg)
        )
        if self.bands is not None and self._frames % s.sighting_every == 0:
            self._last_sightings = self.bands.find(pf)
        self._frames += 1
        sightings = self._last_sightings
        raws_found = (
            find_blobs(fg, motion.moving, s, wrap=self.geometry.wraps, check_frac=False, links=before_vote)
            if motion.reportable
            else []
        )
        if self._tracker is None:
            self._tracker = Tracker2D(s.track_gate_px, s.track_max_missed, float(width) if self.geometry.wraps else 0.0)
        predicted = (
            [u for u, _ in self._tracker.predicted(s.track_split_hits, TRACK_SPLIT_MISSED)]
            if s.track_split_hits > 0
            else []
        )
        raws, was_cut = [], []
        for raw in raws_found:
            for head_part in split_at_heads(raw, motion.moving, s, width):
                split = split_by_tracks(head_part, predicted, motion.moving, s, width)
                for part in split:
                    if part.changed_frac >= s.min_changed_frac:
                        raws.append(part)
                        was_cut.append(len(split) > 1)
        people = []
        cut: list[bool] = []
        n_body = 0
        bg = self.background.background if s.head_edges else None
        for raw, raw_cut in zip(raws, was_cut, strict=True):
            if sightings and is_body_blob(raw.u0, raw.w, width, sightings, v0=raw.v0):
                n_body += 1
                continue
            people.append(annotate(raw, pf, self.geometry, s.head_ratio, s.hist_bins, background=bg))
            cut.append(raw_cut)
        ids = self._tracker.update(
            [(f.head_u_px % width if self.geometry.wraps else f.head_u_px, f.head_v_px) for f in people], cut
        )
        if motion.state == "ok":
            # Not on a light jump's frame: its objects are unknown (nothing was detected), and blending
            # it in would paint the people standing there into the background.
            self.background.update(grey, motion.fg, [(r.u0, r.v0, r.w, r.h) for r in raws])
        features = Features(
            sensor_id=self.sensor_id,
            seq=self.seq,
            stamp_ns=stamp_ns,
            frame_index=frame_index,
            blobs=[to_wire(f, i) for f, i in zip(people, ids, strict=True)][:256],
            sightings=[b.sighting for b in sightings][:32],
            state=DETECTOR_STATE[motion.state],
        )
        self.seq += 1
        return FrameResult(features, motion.state, n_body, pf)
