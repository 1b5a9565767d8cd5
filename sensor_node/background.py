"""Stage 2: moving-object detection by the paper's background model.

The paper ("Moving object detection and extraction", after its ref. [9])
integrates four parts, all here:

* **background subtraction** -- ``|I - B| > fg_threshold`` marks changed pixels;
* **frame differencing** -- ``|I_t - I_{t-1}| > diff_threshold`` marks moving
  pixels; it tells a *sudden* global change (every pixel jumps between two
  frames) from people, and gives each blob its motion evidence;
* **abnormal-change detection** -- when more than ``abnormal_frac`` of the
  image changed at once (a light switched, the camera moved), the model is
  re-initialised instead of reporting the whole image as people: first by a
  smooth gain map around the robust global gain ``median(I / B)`` (a light
  change scales the scene), and if that does not explain the change (the
  robot drives, the scene changed) by learning afresh from still frames;
* **background update** -- ``B <- (1 - a) B + a I`` pixel-wise, *only outside
  object regions* (the caller passes the mask of accepted objects), so people
  who pause are not absorbed while the slow light drift is followed.

The model starts from the per-pixel median of ``warmup_frames`` frames taken
every ``warmup_stride`` frames, so people walking through the first second do not leave ghosts.
Nothing is reported while warming up or on the frame of a re-initialisation.

Works on one grey channel (the panorama's luminance): the cheapest signal that
carries the silhouette; colour is used later, on blob regions only.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Any, Literal

import cv2
import numpy as np
import numpy.typing as npt

from sensor_node.config import PipelineSettings
from sensor_node.ghosts import UnderGhosts, start_up_hole, surround_deviation

__all__ = ["BackgroundModel", "Motion", "MotionState"]

logger = logging.getLogger(__name__)

Mask = npt.NDArray[Any]
"""An 8-bit single-channel image (cv2 results are typed loosely)."""
MotionState = Literal["warmup", "ok", "relit", "reinit", "moving"]


@dataclass(frozen=True, slots=True)
class Motion:
    """What changed in one frame."""

    fg: Mask
    """255 where the frame differs from the background (empty unless state is "ok" or "relit")."""
    moving: Mask
    """255 where the frame differs from the previous frame."""
    state: MotionState
    """"warmup": still learning; "ok"; "relit": a global light change was compensated by a gain;
    "reinit": the background was re-initialised from this frame (nothing reported); "moving": the
    camera itself moves (a robot driving): nothing reported, the background is learnt once it stops."""
    changed_frac: float
    """Fraction of pixels in ``fg`` (before any re-initialisation)."""
    gain: float = 1.0
    """Global brightness gain applied to the background on a light change (1: none)."""

    @property
    def reportable(self) -> bool:
        return self.state in ("ok", "relit")


class BackgroundModel:
    """Per-camera background model on grey frames of a fixed size.

    Args:
        settings: the ``[pipeline]`` knobs (thresholds, learning rate, abnormal fraction, warm-up).
        fast_start: warm up from consecutive frames (a camera that just moved), not every
            ``warmup_stride``-th.
        mobile: the camera is on a robot that may drive (enables the camera-motion test).
    """

    def __init__(self, settings: PipelineSettings, fast_start: bool = False, mobile: bool = False) -> None:
        self.settings = settings
        self.mobile = mobile
        """The camera rides a robot: watch for its own motion (``ego_motion_frac``). A static or PTZ
        camera never does (a PTZ head's moves are known): a crowd filling a narrow view is not ego-motion."""
        self._bg: npt.NDArray[np.float32] | None = None
        self._bg_u8: Mask | None = None
        self._prev: Mask | None = None
        self._warm: list[Mask] = []
        self._warm_seen = 0
        self._stride = 1 if fast_start else settings.warmup_stride
        """Warm-up stride now: 1 when relearning after the camera moved (it must see again soon;
        the ghost checks clean up after anyone who stood still), else ``warmup_stride``."""
        self._static: Mask | None = None
        self._born: Mask | None = None
        """Changed pixels that have stayed changed since the model was learnt, or since the last of its first
        ``BORN_FRAMES`` normal frames: where a start-up hole can be."""
        self._born_first: Mask | None = None
        """Changed pixels that have stayed changed since the model was learnt: someone who came in later
        cannot be among them."""
        self._born_age = 0
        """Normal frames seen since the model was learnt (up to the re-seeding of ``_born``)."""
        self._under: UnderGhosts | None = None
        """The model from under absorbed ghosts: put back where the frame shows it again (a mistake)."""
        self._last_fg: Mask | None = None
        """Objects of the last normal frame: kept out of the light-change estimate."""
        self._frames = 0
        self._updates = 0
        self.reinits = 0
        """Times the model was re-initialised from a frame."""
        self.relights = 0
        """Times a global light change was compensated by a gain."""
        self.ghosts = 0
        """Ghost blobs (objects that left the background) absorbed."""
        self.kept = 0
        """Still-region tests that found a paused object (its outline in the frame) and kept it."""
        self.restored = 0
        """Regions of the model under an absorbed ghost put back (the frame showed them again: a mistake)."""
        self.ego_frames = 0
        """Frames in which the camera itself was seen to move."""

    @property
    def ready(self) -> bool:
        return self._bg is not None

    @property
    def background(self) -> Mask | None:
        """The current background as an 8-bit image (None while warming up)."""
        return self._bg_u8

    def _set_background(self, bg: npt.NDArray[np.float32]) -> None:
        self._bg = bg
        self._bg_u8 = cv2.convertScaleAbs(bg)

    def apply(self, grey: Mask) -> Motion:
        """Classify the pixels of one grey frame (H, W) uint8 against the model."""
        s = self.settings
        self._frames += 1
        prev = self._prev
        self._prev = grey
        moving = _threshold(cv2.absdiff(grey, prev), s.diff_threshold) if prev is not None else np.zeros_like(grey)
        empty = np.zeros_like(grey)
        ego = prev is not None and self._camera_moves(grey, prev, moving)
        if ego:
            self.ego_frames += 1
        if self._bg is None:
            if ego or (prev is not None and cv2.countNonZero(moving) > 0.5 * s.abnormal_frac * grey.size):
                # The camera is moving (or the light flickers): learn only from a still view.
                self._warm, self._warm_seen = [], 0
                if ego:
                    return Motion(empty, moving, "moving", 0.0)
            else:
                if self._warm_seen % self._stride == 0:
                    self._warm.append(grey.copy())
                self._warm_seen += 1
            if len(self._warm) >= s.warmup_frames:
                stack = np.stack(self._warm)
                self._set_background(np.median(stack, axis=0).astype(np.float32))
                self._warm, self._warm_seen = [], 0
                logger.debug("background initialised from %d frames", s.warmup_frames)
            return Motion(empty, moving, "warmup", 0.0)
        if ego:
            # Known ego-motion is not available: the background no longer fits the view. Forget it
            # now (not after it has soaked up the moving scene) and learn it afresh once stopped.
            self._restart(1.0, 1.0, "the camera moves")
            return Motion(empty, moving, "moving", 1.0)
        bg_u8 = self._bg_u8
        assert bg_u8 is not None
        fg = _threshold(cv2.absdiff(grey, bg_u8), s.fg_threshold)
        n = grey.size
        frac = cv2.countNonZero(fg) / n
        if frac <= s.abnormal_frac:
            # Born: changed ever since the model was learnt. Someone standing in the view while it was
            # learnt is in the model, and their hole opens only as they walk off: what is changed at the
            # end of the model's first BORN_FRAMES counts too (not what changed meanwhile and left: anyone
            # in view then would count).
            self._born_age += 1
            if self._born is None or self._born_first is None:
                self._born, self._born_first = fg.copy(), fg.copy()
            else:
                cv2.bitwise_and(self._born_first, fg, dst=self._born_first)
                if self._born_age == BORN_FRAMES:
                    self._born = fg.copy()
                else:
                    cv2.bitwise_and(self._born, fg, dst=self._born)
            self._update_static(grey, fg, moving)
            self._last_fg = fg
            return Motion(fg, moving, "ok", frac)
        # Abnormal change: many pixels changed. A light change scales the scene by a gain -- not
        # quite uniformly (lamps, windows, saturated highlights), so the gain is a smooth map.
        gain = _global_gain(grey, bg_u8)
        assert self._bg is not None
        if abs(gain - 1.0) < MIN_LIGHT_STEP:
            return self._restart(frac, gain, "the view changed, not the light")
        new_bg = self._bg * _gain_map(grey, bg_u8, gain, self._last_fg)
        # Where the scaled background nears saturation, colour channels clip one by one and the grey
        # level is no longer a product: take what the camera sees there -- where the camera sees a
        # bright surface too, not a person standing in front of it (who would become background).
        near = (new_bg > 230.0) & (grey > 230)
        new_bg[near] = grey[near]
        np.minimum(new_bg, 255.0, out=new_bg)
        fg2 = _threshold(cv2.absdiff(grey, cv2.convertScaleAbs(new_bg)), s.fg_threshold)
        frac2 = cv2.countNonZero(fg2) / n
        if frac2 <= s.abnormal_frac:
            self._set_background(new_bg)
            self.relights += 1
            self._under = None
            logger.info("sudden light change (gain %.3f, %.0f%% changed): background rescaled", gain, 100 * frac)
            # The frame of the jump is not reported: frame differencing is meaningless across it.
            return Motion(empty, empty, "relit", frac, gain)
        return self._restart(frac, gain, "not explained by a light change")

    def _camera_moves(self, grey: Mask, prev: Mask, moving: Mask) -> bool:
        """Frame differencing says the camera itself moves: motion in most directions at once.

        People move in a few compact column ranges; when the robot carrying the
        camera drives, every textured part of the room shifts, so most of the
        ``EGO_SECTORS`` column sectors hold moving pixels. A sudden light change
        does too, but it is a global gain between the two frames, not motion.
        """
        frac = self.settings.ego_motion_frac
        if frac >= 1.0 or not self.mobile:
            return False
        cols = cv2.reduce(moving, 0, cv2.REDUCE_SUM, dtype=cv2.CV_32S).ravel()
        n = cols.size - cols.size % EGO_SECTORS
        if n < EGO_SECTORS:
            return False
        sectors = cols[:n].reshape(EGO_SECTORS, -1).sum(axis=1) // 255
        if int(np.count_nonzero(sectors >= EGO_SECTOR_PX)) < frac * EGO_SECTORS:
            return False
        return abs(_global_gain(grey, prev) - 1.0) < MIN_LIGHT_STEP

    def _restart(self, frac: float, gain: float, why: str) -> Motion:
        """Re-initialise: forget the background and learn it again from the next still frames.

        A moving camera (a robot driving) or a changed scene cannot be compensated;
        learning afresh from a median of still frames (rather than from this one
        frame) keeps the people now in view out of the new background.
        """
        self._bg = None
        self._bg_u8 = None
        self._warm, self._warm_seen = [], 0
        self._stride = 1
        self._static = None
        self._born = None
        self._born_first = None
        self._born_age = 0
        self._under = None
        self.reinits += 1
        logger.info("abnormal change (%.0f%% of pixels changed, gain %.3f, %s): relearning", 100 * frac, gain, why)
        empty = np.zeros(self._prev.shape if self._prev is not None else (1, 1), np.uint8)
        return Motion(empty, empty, "reinit", frac, gain)

    def update(self, grey: Mask, fg: Mask | None = None, boxes: list[tuple[int, int, int, int]] | None = None) -> None:
        """Weighted-average update of the background outside object regions.

        Object regions are the changed pixels ``fg`` (grown by 2 px) and the
        boxes (u0, v0, w, h; wrapping) of the accepted blobs (grown by 2 px): no
        part of a person, even one that fell out of its blob, is learnt.

        Runs every ``update_every`` frames with the learning rate scaled to match.
        Object regions take none of the current frame (paper: update only in the
        non-object regions), but they follow the global light drift measured
        outside them: otherwise a region that held a person for a while would
        keep the old brightness and later show as a false object.
        """
        if self._bg is None:
            return
        self._updates += 1
        k = self.settings.update_every
        if self._updates % k:
            return
        alpha = min(1.0, self.settings.learning_rate * k)
        objects = _object_mask(grey.shape, fg, boxes or [])
        if objects is None:
            cv2.accumulateWeighted(grey, self._bg, alpha)
        else:
            outside = cv2.bitwise_not(objects)
            before = cv2.mean(self._bg, mask=outside)[0]
            cv2.accumulateWeighted(grey, self._bg, alpha, mask=outside)
            after = cv2.mean(self._bg, mask=outside)[0]
            if before > 1.0:
                drift = self._bg * np.float32(after / before)
                cv2.copyTo(drift, objects, self._bg)
        self._bg_u8 = cv2.convertScaleAbs(self._bg)

    def _update_static(self, grey: Mask, fg: Mask, moving: Mask) -> None:
        """Count, per pixel, the frames it has been changed-but-still; absorb ghosts among them.

        A *ghost* -- something that was in the background and left (a person who
        stood still while the model learnt) -- changes pixels like a person does
        but never moves. Regions that stayed changed and still for
        ``ghost_frames`` are checked: a ghost's outline is an edge of the
        background image but not of the current frame (where the wall is
        smooth), a paused person's outline the reverse. Ghosts are copied into
        the background; people who stand still are kept while they stand (their
        outline is an edge of the frame, not of the model) up to
        ``still_keep_frames`` -- a ghost revealing a contrasted background (a
        white post where someone stood) passes that test too and must not stay
        for ever; a still region that neither test recognises (on a textured floor) becomes
        background after ``still_absorb_frames``, so no ghost stays.

        The surface beside a region is a second test (:func:`~sensor_node.ghosts.surround_deviation`):
        a region changed ever since the model was young (*born*) is a start-up hole unless the frame,
        not the model, clearly departs from the surface beside it (:func:`~sensor_node.ghosts.start_up_hole`),
        absorbed at its first test whatever its outline says (a plain shirt before a textured wall; a
        grey shirt held where the frame shows a bright ceiling corner); an outline "ghost" whose frame
        is no closer to its surroundings than the model is, is not absorbed.
        What an absorption overwrote (outside start-up holes) is kept a while and put back where
        the frame shows it again (:class:`~sensor_node.ghosts.UnderGhosts`).
        """
        s = self.settings
        # Sampled every STATIC_EVERY frames (cheap; ghosts are not urgent): the counter counts samples.
        if self._frames % STATIC_EVERY or self._bg_u8 is None:
            return
        still = cv2.bitwise_and(fg, cv2.bitwise_not(moving))
        if self._static is None:
            self._static = np.zeros_like(grey)
        self._static = cv2.bitwise_and(cv2.add(self._static, 1, mask=still), still)  # type: ignore[call-overload]
        if self._under is not None and self._under.expired(self._frames):
            self._under = None  # everything it kept is too old to put back
        if self._under is not None and self._bg is not None:
            back, regions = self._under.restore(
                grey, still, self._bg, frame=self._frames, match_level=s.fg_threshold, least_px=s.min_blob_px
            )
            self.restored += regions
            if back is not None:
                self._static[back > 0] = 0
                self._bg_u8 = cv2.convertScaleAbs(self._bg)
        samples = max(1, min(254, -(-s.ghost_frames // STATIC_EVERY)))
        old = cv2.threshold(self._static, samples - 1, 255, cv2.THRESH_BINARY)[1]
        if cv2.countNonZero(old) == 0:
            return
        # Whole regions, not the speckle of their flat insides: a ghost test on a ragged outline
        # would measure texture, not the silhouette.
        old = cv2.morphologyEx(old, cv2.MORPH_CLOSE, _K5)
        n, labels, stats, _ = cv2.connectedComponentsWithStats(old, connectivity=8)
        long_still = max(samples, min(254, -(-s.still_absorb_frames // STATIC_EVERY)))
        keep_still = max(long_still, min(254, -(-s.still_keep_frames // STATIC_EVERY)))
        absorbed = False
        for k in range(1, n):
            x, y, w, h, area = (int(v) for v in stats[k])
            mask = labels[y : y + h, x : x + w] == k
            if area < s.min_blob_px or area < 0.3 * w * h:
                # Too small or too ragged for an outline test: a speck, or a sliver of a ghost's edge
                # left by an absorption (the model there still holds the person's outline, a few grey
                # levels over the threshold). Changed pixels are never learnt, so it would stay for
                # ever and join the blob of whoever passes it: it becomes background after
                # still_absorb_frames too, unless changed pixels surround it (part of someone). What it
                # overwrote is kept: the part of someone that alone differs from the wall (a shirt of the
                # wall's grey in front of a poster) comes back when they walk on.
                if int(self._static[y : y + h, x : x + w][mask].max()) >= long_still and self._absorb(
                    grey, fg, moving, mask, (x, y), keep=True, fringe=False
                ):
                    absorbed = True
                    logger.debug("still fragment of %d px at column %d absorbed", area, x)
                continue
            outline = cv2.morphologyEx(mask.astype(np.uint8), cv2.MORPH_GRADIENT, _K3) > 0
            cur = cv2.morphologyEx(grey[y : y + h, x : x + w], cv2.MORPH_GRADIENT, _K3)
            was = cv2.morphologyEx(self._bg_u8[y : y + h, x : x + w], cv2.MORPH_GRADIENT, _K3)
            was_sum, n_out = float(was[outline].sum()), max(1, int(np.count_nonzero(outline)))
            cur_sum = float(cur[outline].sum())
            age = int(self._static[y : y + h, x : x + w][mask].max())
            score = was_sum / (cur_sum + 1.0)
            # A ghost's outline is a real silhouette edge in the background (not two flat surfaces
            # whose ratio is noise: the still inside of a slowly walking person's shirt).
            ghost = score >= GHOST_SCORE and was_sum / n_out >= GHOST_EDGE
            # The surface beside the region decides too: a hole shows in the frame what continues on
            # both sides, while the model holds the one who left. It overrules the outline test when
            # the frame is no closer to the surroundings than the model is (someone standing in front
            # of a window: its frame is a strong outline of the model, but that is no ghost).
            born = self._born is not None and bool(
                np.count_nonzero(self._born[y : y + h, x : x + w][mask]) >= 0.5 * area
            )
            # Neither an outline ghost nor a start-up hole: no surround can make it one (not computed).
            dev_cur, dev_bg = surround_deviation(grey, self._bg_u8, fg, mask, (x, y)) if ghost or born else (0.0, 0.0)
            hole = born and dev_cur + dev_bg > 0.0 and start_up_hole(dev_cur, dev_bg)
            # Changed since the model was learnt, the model holds whoever stood there: nothing to put
            # back. Changed since the end of its first BORN_FRAMES only, it may be someone who came in
            # meanwhile and stands (in front of a window, looking like its hole): keep what was there.
            first = (
                hole
                and self._born_first is not None
                and bool(np.count_nonzero(self._born_first[y : y + h, x : x + w][mask]) >= 0.5 * area)
            )
            if dev_cur + dev_bg > 0.0:
                ghost = hole or (ghost and dev_cur < dev_bg)
            logger.debug(
                "still region x=%d w=%d area=%d: bg edge %.1f, frame edge %.1f, age %d, ghost %s, dev cur %.1f bg %.1f",
                x,
                w,
                area,
                was_sum / n_out,
                cur_sum / n_out,
                age,
                ghost,
                dev_cur,
                dev_bg,
            )
            if not ghost:
                # A paused person is the reverse: the silhouette is an edge of the current frame, not of
                # the background. They stay an object region (never learnt) however long they stand;
                # only what neither test recognises becomes background after still_absorb_frames.
                if cur_sum >= PERSON_SCORE * (was_sum + 1.0) and cur_sum / n_out >= GHOST_EDGE and age < keep_still:
                    self.kept += 1
                    continue
                if age < long_still:
                    continue
            # Anything but a hole since the model was learnt may be a mistake -- a born region too:
            # someone in view since the model was young who stood still -- keep what was there.
            if self._absorb(grey, fg, moving, mask, (x, y), keep=not first):
                absorbed = True
                logger.debug("ghost of %d px at column %d absorbed (edge score %.2f)", area, x, score)
        if absorbed and self._bg is not None:
            self._bg_u8 = cv2.convertScaleAbs(self._bg)

    def _absorb(
        self,
        grey: Mask,
        fg: Mask,
        moving: Mask,
        mask: npt.NDArray[np.bool_],
        origin: tuple[int, int],
        *,
        keep: bool,
        fringe: bool = True,
    ) -> bool:
        """Copy a still region (``mask`` in its box at ``origin`` = (column, row)) of the frame into the model.

        With ``fringe``, the ghost's fringe too: its changed, not moving pixels up to 4 px around the
        region (not the edge of someone walking past it); without, the region's own not moving pixels
        only (a fragment: what is around it may be someone whose rest matches the wall). Not if the
        region continues into changed pixels all around (``GHOST_RING_CHANGED``). ``keep``: remember the model it
        overwrote (:class:`UnderGhosts`). Returns whether it was absorbed (``_bg_u8`` is left to the caller).
        """
        assert self._bg is not None and self._static is not None
        x, y = origin
        h, w = mask.shape
        y0, y1, x0, x1 = max(0, y - 4), min(grey.shape[0], y + h + 4), max(0, x - 4), min(grey.shape[1], x + w + 4)
        region = np.zeros((y1 - y0, x1 - x0), np.uint8)
        region[y - y0 : y - y0 + h, x - x0 : x - x0 + w][mask] = 255
        grown = cv2.dilate(region, _K9) > 0
        ring = grown & (region == 0)
        around = np.count_nonzero(ring & (fg[y0:y1, x0:x1] > 0))
        if around > GHOST_RING_CHANGED * np.count_nonzero(ring):
            # A ghost is the whole changed region (beyond it the frame matches the model); this one
            # continues into changed pixels all around: the still inside of someone walking (a
            # uniform shirt does not change from frame to frame). Learning it would paint them in.
            return False
        take = (grown & (fg[y0:y1, x0:x1] > 0) if fringe else region > 0) & (moving[y0:y1, x0:x1] == 0)
        sub = self._bg[y0:y1, x0:x1]
        if keep:
            if self._under is None:
                self._under = UnderGhosts(grey.shape)
            self._under.keep((x0, y0), take, sub, self._frames)
        sub[take] = grey[y0:y1, x0:x1][take]
        self._static[y0:y1, x0:x1][take] = 0
        self.ghosts += 1
        return True


EGO_SECTORS = 36
"""Column sectors (10 degrees each on a panorama) of the camera-motion test."""

EGO_SECTOR_PX = 10
"""Moving pixels that make a sector count as moving in the camera-motion test."""

STATIC_EVERY = 4
"""Frames between samples of the changed-but-still counter (ghost detection)."""

BORN_FRAMES = 30
"""Normal frames (2 s at 15 fps) after the model is learnt during which someone who stood in the view while
it was learnt can walk off and leave a start-up hole (changed pixels still changed at the end of them)."""

MIN_LIGHT_STEP = 0.04
"""A global gain closer to 1 than this is no light change: the abnormal change is the view itself."""

GHOST_EDGE = 10.0
"""Least mean edge strength (grey levels, 3x3 morphological gradient) of a ghost's outline in the background."""

GHOST_SCORE = 2.5
"""Background-outline / frame-outline edge ratio above which a still region is a ghost (people: < 1)."""

GHOST_RING_CHANGED = 0.35
"""Fraction of the 4-px ring around a still region that may be changed for it to be absorbed as a ghost."""

PERSON_SCORE = 1.5
"""Frame-outline / background-outline edge ratio above which a still region is a paused object, kept."""

_K3 = np.ones((3, 3), np.uint8)
_K5 = np.ones((5, 5), np.uint8)
_K9 = np.ones((9, 9), np.uint8)


def _object_mask(shape: tuple[int, ...], fg: Mask | None, boxes: list[tuple[int, int, int, int]]) -> Mask | None:
    """255 on the changed pixels and blob boxes, grown by 2 px; None if there is nothing."""
    if fg is not None and cv2.countNonZero(fg) > 0:
        mask = cv2.dilate(fg, _K5)
    elif boxes:
        mask = np.zeros(shape[:2], np.uint8)
    else:
        return None
    width = mask.shape[1]
    for u0, v0, w, h in boxes:
        rows = slice(max(0, v0 - 2), v0 + h + 2)
        a, b = u0 - 2, u0 + w + 2
        if a < 0:
            mask[rows, a % width :] = 255
        if b > width:
            mask[rows, : b - width] = 255
        mask[rows, max(a, 0) : min(b, width)] = 255
    return mask


def _threshold(diff: Mask, level: int) -> Mask:
    return cv2.threshold(diff, level, 255, cv2.THRESH_BINARY)[1]


def _gain_map(
    grey: Mask, bg: Mask, gain: float, objects: Mask | None = None, block: int = 16
) -> npt.NDArray[np.float32]:
    """Per-pixel brightness ratio frame/background, smooth: block medians of the ratio.

    A median over 7 x 7 blocks of ``block`` px (about 110 px, several people wide)
    ignores the people, a minority of any such neighbourhood; the ``objects`` of
    the frame before the jump (grown) are left out altogether, so a person close
    to the camera, filling a neighbourhood, does not set its light. Pixels
    without a usable ratio take the global ``gain``. The ratio is quantised to 1 %.
    """
    h, w = grey.shape
    g = grey.astype(np.float32)
    b = bg.astype(np.float32)
    usable = (b > 16) & (g < 250)
    if objects is not None and objects.shape == grey.shape:
        usable &= cv2.dilate(objects, _K9) == 0
    ratio = np.where(usable, g / np.maximum(b, 1.0), np.float32(gain)).astype(np.float32)
    small = cv2.resize(ratio, (max(1, w // block), max(1, h // block)), interpolation=cv2.INTER_AREA)
    q = np.clip(small * 100.0 + 0.5, 1, 255).astype(np.uint8)  # medianBlur > 5 needs 8 bits
    smooth = cv2.medianBlur(q, 7).astype(np.float32) / np.float32(100.0)
    return cv2.resize(smooth, (w, h), interpolation=cv2.INTER_LINEAR).astype(np.float32)


def _global_gain(grey: Mask, bg: Mask) -> float:
    """Robust global brightness ratio frame/background: median over a pixel grid, ignoring dark pixels."""
    g = grey[::4, ::4].astype(np.float32)
    b = bg[::4, ::4].astype(np.float32)
    ok = (b > 16) & (g > 4) & (g < 250)
    if int(np.count_nonzero(ok)) < 16:
        return 1.0
    return float(np.median(g[ok] / b[ok]))
