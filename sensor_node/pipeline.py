"""The image pipeline of one camera: frame in, Features out (pure: no zenoh, no clock).

Panoramic cameras, in the order :meth:`ImagePipeline.process` runs them: annular frame -> unwarp
(grey panorama, reduced colour) -> background model (changed pixels) -> shadows and highlights
removed, majority vote -> segmentation: blobs -> split at head valleys -> split between the 2D
tracks' predicted heads -> (robot bodies, and the holes robots left in the model, removed) -> head +
annotation -> 2D tracks -> Features, then the background update outside this frame's objects; with the
sightings of other robots (Eq. 3) every ``sighting_every`` frames. Two results feed later frames: the
2D tracks' predicted heads drive the next frame's group splits, and each frame's objects keep the
background update off the people. Perspective (PTZ) cameras skip the unwarp and the sightings and report world
azimuths; the background model restarts whenever the head moves.

Performance: the background model works on one grey channel at panorama
resolution; colour (histograms, band search) is used only inside blob boxes
and below the horizon; the background update runs every ``update_every``
frames. ``benchmarks/bench_pipeline.py`` measures it against an OpenCV floor.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from common.arrays import Image, Mask
from common.errors import SourceError
from common.schema import DetectorState, Features
from sensor_node.background.model import BackgroundModel, Motion, MotionState
from sensor_node.config import BodySpec, PipelineSettings
from sensor_node.features import (
    BlobFeature,
    ImageGeometry,
    PanoramicGeometry,
    PinholeGeometry,
    annotate,
    to_wire,
)
from sensor_node.segmentation.blobs import RawBlob, find_blobs
from sensor_node.segmentation.groups import split_by_tracks
from sensor_node.segmentation.head_splits import split_at_heads, top_profile
from sensor_node.sightings import BandFinder, BodySighting, LeftPlaces, is_body_blob
from sensor_node.tracks2d import Tracker2D
from sensor_node.unwarp import PanoFrame, Unwarper

__all__ = ["FrameResult", "ImagePipeline"]


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
    fg = background.without_shadows(motion.fg, floor)
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


@dataclass(frozen=True, slots=True)
class Segment:
    """One object of a frame, as segmentation left it."""

    blob: RawBlob
    cut: bool
    """Cut from a group by the 2D tracks' predicted heads (its track does not count it a solo hit)."""


def segment(
    fg: Mask,
    links: Mask,
    settings: PipelineSettings,
    *,
    wrap: bool,
    predicted_heads: list[float],
) -> list[Segment]:
    """The objects of one frame: the changed pixels grouped into blobs, each split at its head valleys
    (:mod:`sensor_node.segmentation.head_splits`) and between the ``predicted_heads`` of the 2D tracks
    inside it (:mod:`sensor_node.segmentation.groups`); a part is kept if enough of its box changed.

    Args:
        fg: the objects' pixels (:func:`objects_mask`).
        links: the changed pixels before the vote, which join a person's parts above one another.
        settings: the blob checks and split knobs.
        wrap: columns wrap around (a panorama).
        predicted_heads: image columns where the 2D tracks expect a head in this frame (from the
            frames before).
    """
    width = fg.shape[1]
    out = []
    for blob in find_blobs(fg, settings, wrap=wrap, check_frac=False, links=links):
        top = top_profile(blob.mask)  # both splits read it
        for head_part in split_at_heads(blob, settings, width, top=top):
            parts = split_by_tracks(head_part, predicted_heads, settings, width, top=top if head_part is blob else None)
            out += [Segment(part, len(parts) > 1) for part in parts if part.changed_frac >= settings.min_changed_frac]
    return out


def people_of(
    objects: list[Segment],
    frame: PanoFrame,
    geometry: ImageGeometry,
    settings: PipelineSettings,
    *,
    sightings: list[BodySighting],
    background: Mask | None,
) -> tuple[list[BlobFeature], list[bool], int]:
    """The objects that are people, annotated (head, bearing, width, colour), with whether each was cut
    from a group, and how many objects were the bodies of robots in ``sightings`` (not people).

    ``background``: the background model's image, for sub-pixel head edges (None: from the mask alone).
    """
    width = frame.grey.shape[1]
    people: list[BlobFeature] = []
    cut: list[bool] = []
    n_body = 0
    for obj in objects:
        raw = obj.blob
        if sightings and is_body_blob(raw.u0, raw.w, width, sightings, v0=raw.v0):
            n_body += 1
            continue
        people.append(annotate(raw, frame, geometry, settings.head_ratio, settings.hist_bins, background=background))
        cut.append(obj.cut)
    return people, cut, n_body


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
        self._left = LeftPlaces(geometry.camera.width_px if isinstance(geometry, PanoramicGeometry) else 0, settings)
        """Where robots that stood in the background model drove off from: their holes are no people."""
        self._frames = 0
        self.seq = 0
        self._floor_key: tuple[int, int, int] | None = None
        self._floor_mask: Mask | None = None

    def _floor(self, pf: PanoFrame) -> Mask | None:
        """255 on the reduced colour image's pixels whose ray points below the horizon (cached per geometry)."""
        if not self.settings.shadows:
            return None
        small_h, small_w = pf.small_shape
        key = (small_h, small_w, id(self.geometry))
        if self._floor_key != key:
            self._floor_mask = below_horizon(self.geometry, small_w, small_h, pf.scale)
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
        """Run every stage on one frame and build its Features (``processing_ms`` left 0).

        The stages in their order; what feeds later frames is passed by name: the 2D tracks'
        ``predicted_heads`` (from the frames before) to segmentation, this frame's ``objects`` to the
        background update.
        """
        s = self.settings
        self._check_size(frame)
        pf = self.unwarper.frame(frame) if self.unwarper is not None else PanoFrame.from_image(frame)
        motion = self.background.apply(pf.grey, stamp_ns, pf if s.shadows else None)
        fg, links = (
            objects_mask(motion, self.background, self._floor(pf)) if motion.reportable else (motion.fg, motion.fg)
        )
        sightings = self._sightings(pf)
        left = self._left_places(sightings, motion.state)
        tracker = self._tracks(pf.grey.shape[1])
        predicted_heads = self._split_heads(tracker)
        objects = (
            segment(fg, links, s, wrap=self.geometry.wraps, predicted_heads=predicted_heads)
            if motion.reportable
            else []
        )
        people, cut, n_body = people_of(
            objects,
            pf,
            self.geometry,
            s,
            sightings=sightings + left,
            background=self.background.background if s.head_edges else None,
        )
        ids = tracker.update(self._head_points(people, pf.grey.shape[1]), cut)
        self._learn_background(pf.grey, motion, objects=objects)
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

    def _check_size(self, frame: Image) -> None:
        """A perspective camera's frames must be the size its calibration is for."""
        if self.unwarper is None and isinstance(self.geometry, PinholeGeometry):
            cam = self.geometry.camera
            h, w = frame.shape[:2]
            if (w, h) != (cam.width_px, cam.height_px):
                raise SourceError(
                    f"frame is {w}x{h} px but the camera calibration is for {cam.width_px}x{cam.height_px} "
                    "(calibration image_size)"
                )

    def _sightings(self, pf: PanoFrame) -> list[BodySighting]:
        """The other robots' bodies: looked for every ``sighting_every`` frames, the last ones in between."""
        if self.bands is not None and self._frames % self.settings.sighting_every == 0:
            self._last_sightings = self.bands.find(pf)
        self._frames += 1
        return self._last_sightings

    def _left_places(self, sightings: list[BodySighting], state: MotionState) -> list[BodySighting]:
        """Where robots that stood in the background model have lately driven off from (:class:`LeftPlaces`)."""
        if state not in ("ok", "relit"):
            self._left.reset()  # learning, or relearning: a new model, new places
            return []
        return self._left.update(sightings, self._frames)

    def _tracks(self, width: int) -> Tracker2D:
        """The 2D tracks (started on the first frame after a reset)."""
        s = self.settings
        if self._tracker is None:
            self._tracker = Tracker2D(s.track_gate_px, s.track_max_missed, float(width) if self.geometry.wraps else 0.0)
        return self._tracker

    def _split_heads(self, tracker: Tracker2D) -> list[float]:
        """The head columns the 2D tracks predict for this frame, of the tracks trusted to split a group."""
        s = self.settings
        if s.track_split_hits <= 0:
            return []
        return [u for u, _ in tracker.predicted(s.track_split_hits, TRACK_SPLIT_MISSED)]

    def _head_points(self, people: list[BlobFeature], width: int) -> list[tuple[float, float]]:
        """The people's head positions in the image (columns wrapped on a panorama), for the 2D tracks."""
        return [(f.head_u_px % width if self.geometry.wraps else f.head_u_px, f.head_v_px) for f in people]

    def _learn_background(self, grey: Mask, motion: Motion, *, objects: list[Segment]) -> None:
        """The background update, outside this frame's changed pixels and ``objects``."""
        if motion.state == "ok":
            # Not on a light jump's frame: its objects are unknown (nothing was detected), and blending
            # it in would paint the people standing there into the background.
            self.background.update(grey, motion.fg, [(o.blob.u0, o.blob.v0, o.blob.w, o.blob.h) for o in objects])
