"""Stage 2: moving-object detection by the paper's background model.

The paper ("Moving object detection and extraction", after its ref. [9])
integrates four parts, all here:

* **background subtraction** -- ``|I - B|`` beyond a per-pixel threshold (``fg_sigmas`` of the
  pixel's own swing or of the image's noise, at least ``fg_threshold``) marks changed pixels; beside
  them (connected), pixels beyond the level the image's own noise rarely reaches join them
  (hysteresis, :meth:`BackgroundModel.apply`): the faint parts of a person (a face or a shirt near
  the wall's grey) come with the parts that stand out, so the clean-up that follows does not erase
  the thin, sparse links between them;
* **frame differencing** -- ``|I_t - I_{t-1}| > diff_threshold`` marks moving
  pixels; it tells a *sudden* global change (every pixel jumps between two
  frames) from people, a camera that moves from people who do, and still
  regions (ghosts, people who pause) from moving ones;
* **abnormal-change detection** -- when more than ``abnormal_frac`` of the
  image changed at once (a light switched, the camera moved), the model is
  re-initialised instead of reporting the whole image as people: first by a
  smooth gain map around the robust global gain ``median(I / B)`` (a light
  change scales the scene), and if that does not explain the change (the
  robot drives, the scene changed) by learning afresh from still frames;
* **background update** -- ``B <- (1 - a) B + a I`` pixel-wise, *only outside
  object regions* (the caller passes the mask of accepted objects), so people
  who pause are not absorbed while the slow light drift is followed; ghosts
  (someone who was in the model and left) are absorbed by the still-region
  stage (:mod:`sensor_node.background.still`).

The model starts from the per-pixel median of ``warmup_frames`` frames taken
every ``warmup_stride`` frames, so people walking through the first second do not leave ghosts.
Nothing is reported while warming up or on the frame of a re-initialisation.

Works on one grey channel (the panorama's luminance): the cheapest signal that
carries the silhouette; colour is used later, on blob regions only.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Literal, cast

import cv2
import numpy as np
import numpy.typing as npt

from common.arrays import Mask
from sensor_node.background.shadows import TEXTURE_WINDOW, ReducedColour, local_spread, shadow_cells
from sensor_node.background.still import StillRegions
from sensor_node.config import PipelineSettings

__all__ = ["BackgroundModel", "FrameDifference", "Motion", "MotionState"]

logger = logging.getLogger(__name__)

"""An 8-bit single-channel image (cv2 results are typed loosely)."""
MotionState = Literal["warmup", "ok", "relit", "reinit", "moving"]


class FrameDifference:
    """255 where a frame differs from the one before by more than ``level`` (frame differencing), computed when
    first asked for: the warm-up, a mobile camera's ego-motion test and the still regions' sampling frames
    read it, the other frames do not."""

    __slots__ = ("_grey", "_level", "_mask", "_prev")

    def __init__(self, grey: Mask, prev: Mask | None, level: int) -> None:
        self._grey, self._prev, self._level = grey, prev, level
        self._mask: Mask | None = None

    @classmethod
    def none(cls, grey: Mask) -> FrameDifference:
        """No moving pixels (a frame whose difference to the one before means nothing)."""
        return cls(grey, None, 0)

    def __call__(self) -> Mask:
        if self._mask is None:
            if self._prev is None:
                self._mask = np.zeros_like(self._grey)
            else:
                self._mask = _threshold(cv2.absdiff(self._grey, self._prev), self._level)
        return self._mask


@dataclass(frozen=True, slots=True)
class Motion:
    """What changed in one frame."""

    fg: Mask
    """255 where the frame differs from the background (empty unless state is "ok" or "relit")."""
    difference: FrameDifference
    """Where the frame differs from the previous frame (:attr:`moving`)."""
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

    @property
    def moving(self) -> Mask:
        """255 where the frame differs from the previous frame."""
        return self.difference()


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
        self._warm_colour: list[Mask] = []
        self._warm_seen = 0
        self._warm_due_ns: int | None = None
        """Stamp at which the next warm-up sample is due (``warmup_s`` / ``warmup_frames`` apart)."""
        self._fast = fast_start
        """Warm up from consecutive frames: relearning after the camera moved (it must see again soon;
        the ghost checks clean up after anyone who stood still)."""
        self._dev: npt.NDArray[np.float32] | None = None
        """Per-pixel typical |frame - background| outside people (grey levels): noise, and the swing of
        what moves in place (a flapping tape, leaves, a screen)."""
        self._thr: Mask | None = None
        """Per-pixel changed threshold (8-bit): ``fg_threshold``, or more where the image is noisy or swings."""
        self._thr_weak: Mask | None = None
        """Per-pixel threshold (8-bit, at most ``_thr``) beyond which a pixel connected to changed pixels
        changed too (None: the noise tail is not measured yet, or the threshold is ``_thr`` everywhere)."""
        self._sigma: npt.NDArray[np.float32] | None = None
        """Per-pixel noise sigma (grey levels): the pixel's own swing or the image's noise, the larger."""
        self._tail_bin: int | None = None
        """The noise tail's bin at the last update (where the next one's search starts)."""
        self.tail_sigmas: float | None = None
        """The image's noise tail: how many of their own sigmas the background pixels' differences pass in a
        fraction ``WEAK_FALSE_RATE`` of them (measured outside objects at each update, smoothed). About 3.7
        for Gaussian noise; more for compressed video (blocks, ringing)."""
        self._colour_bg: npt.NDArray[np.float32] | None = None
        """Reduced colour background (the frames' :attr:`PanoFrame.small`), for the shadow test."""
        self._colour_now: ReducedColour | None = None
        self._colour_rows: tuple[int, int] = (0, 1 << 30)
        """Rows [r0, r1) of the colour background the shadow test reads: the floor's (the ``floor`` given to
        :meth:`without_shadows`) and the texture window's reach around them. Only they are learnt (the floor is
        the same for a model's life: a camera that turns gets a new model)."""
        self._floor: Mask | None = None
        self._bg_spread: npt.NDArray[np.float32] | None = None
        """The colour background's local texture (:func:`sensor_node.background.shadows.local_spread`),
        computed when the shadow test first needs it after the colour background changed."""
        self.noise_sigma = 0.0
        """The image's own noise: robust sigma of |frame - background| over the background (grey levels)."""
        self.still = StillRegions(settings)
        """Changed-but-still regions: ghosts absorbed, people who pause kept (:mod:`sensor_node.background.still`)."""
        self._last_fg: Mask | None = None
        """Objects of the last normal frame: kept out of the light-change estimate."""
        self._frames = 0
        self._updates = 0
        self.reinits = 0
        """Times the model was re-initialised from a frame."""
        self.relights = 0
        """Times a global light change was compensated by a gain."""
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

    def _take_warm(self, stamp_ns: int | None) -> bool:
        """Whether this still frame is a warm-up sample: ``warmup_frames`` samples over ``warmup_s``."""
        s = self.settings
        if self._fast:
            return True
        if stamp_ns is None or s.warmup_stride > 0:
            take = self._warm_seen % max(1, s.warmup_stride) == 0
            self._warm_seen += 1
            return take
        if self._warm_due_ns is not None and stamp_ns < self._warm_due_ns:
            return False
        # Next sample one interval after this one's stamp (or its due time, if the frame was late).
        base = stamp_ns if self._warm_due_ns is None else max(self._warm_due_ns, stamp_ns - WARM_SLACK_NS)
        self._warm_due_ns = base + round(s.warmup_s * 1e9 / max(1, s.warmup_frames - 1)) - WARM_SLACK_NS
        return True

    def _learn_warm(self) -> None:
        """The model from the warm-up samples: their per-pixel median, and how far each pixel swings about it."""
        stack = np.stack(self._warm)
        bg = np.median(stack, axis=0).astype(np.float32)
        self._set_background(bg)
        # A pixel's typical deviation over the samples (their median: people walking through are a minority
        # of the samples, a tape flapping in the wind is not).
        dev = np.median(np.abs(stack.astype(np.float32) - bg[None]), axis=0).astype(np.float32)
        self._dev = dev
        self._refresh_threshold()
        if self._warm_colour and len(self._warm_colour) == len(self._warm):
            self._colour_bg = np.median(np.stack(self._warm_colour), axis=0).astype(np.float32)
            self._bg_spread = None
        self._warm, self._warm_colour, self._warm_seen, self._warm_due_ns = [], [], 0, None
        logger.debug("background initialised from %d frames (noise sigma %.1f)", stack.shape[0], self.noise_sigma)

    def _refresh_threshold(self) -> None:
        """Per-pixel thresholds from the deviation map.

        Changed: beyond ``fg_sigmas`` of the pixel's own swing or of the image's noise, whichever is larger,
        and never below ``fg_threshold``. Joining changed pixels it touches (:func:`_hysteresis`): beyond the
        level of the image's noise tail (:attr:`tail_sigmas`, at least ``fg_sigmas``) without the
        ``fg_threshold`` floor: on a clean image what passes it beside an object is part of the object; on
        compressed video, whose noise has long tails, it rises to the changed threshold and changes nothing.
        """
        assert self._dev is not None
        s = self.settings
        self.noise_sigma = MAD_TO_SIGMA * float(np.median(self._dev[::4, ::4]))
        # Each operation by whichever of numpy and OpenCV is faster at it (numpy: float products and sums
        # with a scalar; OpenCV: maxima and minima with one, saturating 8-bit conversion).
        # (OpenCV's type stubs before 5.1 reject these calls' overloads, so the ignores may go unused.)
        sigma = cv2.max(self._dev * np.float32(MAD_TO_SIGMA), max(self.noise_sigma, MIN_SIGMA))  # type: ignore[call-overload, unused-ignore]
        self._sigma = cast("npt.NDArray[np.float32]", sigma)
        thr = cv2.min(cv2.max(cv2.convertScaleAbs(sigma, alpha=s.fg_sigmas), s.fg_threshold), 254)  # type: ignore[call-overload, unused-ignore]
        self._thr = thr
        if self.tail_sigmas is None:
            self._thr_weak = None
        else:
            weak = cv2.min(cv2.convertScaleAbs(sigma, alpha=max(s.fg_sigmas, self.tail_sigmas)), thr)
            # Nowhere below the changed threshold (a noise tail as long as it: compressed video): hysteresis
            # would join nothing; it is skipped until the thresholds change.
            self._thr_weak = weak if cv2.countNonZero(cv2.subtract(thr, weak)) else None

    def without_shadows(self, fg: Mask, floor: Mask | None = None) -> Mask:
        """``fg`` without the changed pixels of this frame that are a cast shadow or a highlight on the background
        (``fg`` itself if there are none, or no colour): the frame there is the background dimmed or brightened,
        hue kept.

        Works on the reduced colour images (the frame's :attr:`PanoFrame.small` given to :meth:`apply`), then
        scaled back to ``fg``'s size; only where ``floor`` (reduced size) is set; see
        :func:`sensor_node.background.shadows.shadow_cells`.
        """
        if self._colour_bg is None or self._colour_now is None or self._bg is None:
            return fg
        small = self._colour_now
        if small.small_shape != self._colour_bg.shape[:2]:
            return fg
        if floor is not self._floor:
            self._floor = floor
            self._colour_rows = _rows_read(floor, self._colour_bg.shape[0])
            self._bg_spread = None
        if self._bg_spread is None:
            r0, r1 = self._colour_rows
            self._bg_spread = np.zeros(self._colour_bg.shape[:2], np.float32)
            if r1 > r0:
                self._bg_spread[r0:r1] = local_spread(self._colour_bg[r0:r1])
        cells = shadow_cells(
            small, self._colour_bg, fg, self.noise_sigma, self.settings, floor=floor, bg_spread=self._bg_spread
        )
        return fg if cells is None else cells.removed_from(fg)

    def apply(self, grey: Mask, stamp_ns: int | None = None, colour: ReducedColour | None = None) -> Motion:
        """Classify the pixels of one grey frame (H, W) uint8 against the model.

        Args:
            grey: the frame.
            stamp_ns: its capture time: the warm-up spans ``warmup_s`` of it (None: frames are counted,
                every ``warmup_stride``-th taken).
            colour: the frame's reduced colour image (a :class:`~sensor_node.unwarp.PanoFrame`: the shadow
                test reads its candidates' pixels, the colour background's update the rows it reads), for the
                colour background that tells shadows from objects (:meth:`without_shadows`); None: grey only.
        """
        s = self.settings
        self._frames += 1
        self._colour_now = colour
        prev = self._prev
        self._prev = grey
        moving = FrameDifference(grey, prev, s.diff_threshold)
        ego = prev is not None and self._camera_moves(grey, prev, moving)
        if ego:
            self.ego_frames += 1
        if self._bg is None:
            return self._warm_up(grey, moving, ego=ego, first=prev is None, stamp_ns=stamp_ns, colour=colour)
        if ego:
            # Known ego-motion is not available: the background no longer fits the view. Forget it
            # now (not after it has soaked up the moving scene) and learn it afresh once stopped.
            self._restart(1.0, 1.0, "the camera moves")
            return Motion(np.zeros_like(grey), moving, "moving", 1.0)
        bg_u8 = self._bg_u8
        assert bg_u8 is not None and self._thr is not None
        diff = cv2.absdiff(grey, bg_u8)
        fg = cv2.compare(diff, self._thr, cv2.CMP_GT)
        n = grey.size
        frac = cv2.countNonZero(fg) / n
        if frac <= s.abnormal_frac:
            assert self._bg is not None
            if self._thr_weak is not None:
                fg = _hysteresis(fg, cv2.compare(diff, self._thr_weak, cv2.CMP_GT))
            if self.still.update(grey, fg, moving, bg=self._bg, bg_u8=bg_u8, frame=self._frames):
                self._bg_u8 = cv2.convertScaleAbs(self._bg)
            self._last_fg = fg
            return Motion(fg, moving, "ok", frac)
        return self._relight(grey, bg_u8, frac)

    def _warm_up(
        self,
        grey: Mask,
        moving: FrameDifference,
        *,
        ego: bool,
        first: bool,
        stamp_ns: int | None,
        colour: ReducedColour | None,
    ) -> Motion:
        """Take one frame towards learning the model (:meth:`apply` before there is one); ``first``: no frame
        before it."""
        s = self.settings
        empty = np.zeros_like(grey)
        if ego or (not first and cv2.countNonZero(moving()) > 0.5 * s.abnormal_frac * grey.size):
            # The camera is moving (or the light flickers): learn only from a still view.
            self._warm, self._warm_colour, self._warm_seen, self._warm_due_ns = [], [], 0, None
            if ego:
                return Motion(empty, moving, "moving", 0.0)
        elif self._take_warm(stamp_ns):
            self._warm.append(grey.copy())
            if colour is not None:
                self._warm_colour.append(colour.small.copy())
        if len(self._warm) >= s.warmup_frames:
            self._learn_warm()
        return Motion(empty, moving, "warmup", 0.0)

    def _relight(self, grey: Mask, bg_u8: Mask, frac: float) -> Motion:
        """An abnormal change (a ``frac`` of the pixels changed): rescale the model if a light change explains
        it, else learn it afresh."""
        s = self.settings
        n = grey.size
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
        near = (new_bg > NEAR_SATURATION) & (grey > NEAR_SATURATION)
        new_bg[near] = grey[near]
        np.minimum(new_bg, 255.0, out=new_bg)
        if self._colour_bg is not None:
            ch, cw = self._colour_bg.shape[:2]
            small_gain = cv2.resize(new_bg / np.maximum(self._bg, 1.0), (cw, ch), interpolation=cv2.INTER_AREA)
            self._colour_bg = np.minimum(self._colour_bg * small_gain[..., None], 255.0).astype(np.float32)
            self._bg_spread = None
        fg2 = _threshold(cv2.absdiff(grey, cv2.convertScaleAbs(new_bg)), s.fg_threshold)
        frac2 = cv2.countNonZero(fg2) / n
        if frac2 <= s.abnormal_frac:
            self._set_background(new_bg)
            self.relights += 1
            self.still.forget_under()
            logger.info("sudden light change (gain %.3f, %.0f%% changed): background rescaled", gain, 100 * frac)
            # The frame of the jump is not reported: frame differencing is meaningless across it.
            return Motion(np.zeros_like(grey), FrameDifference.none(grey), "relit", frac, gain)
        return self._restart(frac, gain, "not explained by a light change")

    def _camera_moves(self, grey: Mask, prev: Mask, moving: FrameDifference) -> bool:
        """Frame differencing says the camera itself moves: motion in most directions at once.

        People move in a few compact column ranges; when the robot carrying the
        camera drives, every textured part of the room shifts, so most of the
        ``EGO_SECTORS`` column sectors hold moving pixels. A sudden light change
        does too, but it is a global gain between the two frames, not motion.
        """
        frac = self.settings.ego_motion_frac
        if frac >= 1.0 or not self.mobile:
            return False
        cols = cv2.reduce(moving(), 0, cv2.REDUCE_SUM, dtype=cv2.CV_32S).ravel()
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
        self._dev = self._thr = self._thr_weak = self._sigma = self._colour_bg = self._bg_spread = None
        self._warm, self._warm_colour, self._warm_seen, self._warm_due_ns = [], [], 0, None
        self._fast = True
        self.still.reset()
        self.reinits += 1
        logger.info("abnormal change (%.0f%% of pixels changed, gain %.3f, %s): relearning", 100 * frac, gain, why)
        empty = np.zeros(self._prev.shape if self._prev is not None else (1, 1), np.uint8)
        return Motion(empty, FrameDifference.none(empty), "reinit", frac, gain)

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

        The deviation map (how far each pixel swings about the model) learns
        everywhere but the blob boxes: changed pixels that make no person -- a
        flapping tape, leaves -- raise their own threshold until they stop
        changing. One sample moves it at most ``DEV_STEP`` times its value, so a
        person missed for a frame or two barely marks the pixels they crossed.
        """
        if self._bg is None:
            return
        self._updates += 1
        k = self.settings.update_every
        if self._updates % k:
            return
        alpha = min(1.0, self.settings.learning_rate * k)
        objects = _object_mask(grey.shape, fg, boxes or [])
        self._update_dev(grey, boxes or [], alpha, objects)
        self._update_colour(objects, alpha)
        if objects is None:
            cv2.accumulateWeighted(grey, self._bg, alpha)
        else:
            outside = cv2.bitwise_not(objects)
            # Means over the outside as dot products with its 0/1 weights (cv2.mean with a mask costs 10x).
            weights = np.float32(outside.ravel()) * np.float32(1.0 / 255.0)
            n_out = max(float(cv2.countNonZero(outside)), 1.0)  # the weights' sum, counted on 8 bits
            before = float(np.dot(self._bg.ravel(), weights)) / n_out
            cv2.accumulateWeighted(grey, self._bg, alpha, mask=outside)
            after = float(np.dot(self._bg.ravel(), weights)) / n_out
            if before > 1.0:
                drift = self._bg * np.float32(after / before)
                cv2.copyTo(drift, objects, self._bg)
        self._bg_u8 = cv2.convertScaleAbs(self._bg)

    def _update_dev(
        self, grey: Mask, boxes: list[tuple[int, int, int, int]], alpha: float, objects: Mask | None
    ) -> None:
        if self._dev is None or self._bg_u8 is None:
            return
        diff = cv2.absdiff(grey, self._bg_u8)
        self._update_tail(diff, objects, alpha)
        cap = self._dev * np.float32(1.0 + DEV_STEP) + np.float32(1.0)
        sample = np.minimum(diff, cap)  # float32, without converting the differences first
        people = _object_mask(grey.shape, None, boxes)
        cv2.accumulateWeighted(sample, self._dev, alpha, mask=None if people is None else cv2.bitwise_not(people))
        self._refresh_threshold()

    def _update_tail(self, diff: Mask, objects: Mask | None, alpha: float) -> None:
        """Measure the image's noise tail (:attr:`tail_sigmas`) on the background pixels of this frame.

        The differences outside objects, each in its own pixel's sigmas, are histogrammed; the level that
        a fraction ``WEAK_FALSE_RATE`` of them pass is blended into the estimate at the update's rate.
        What passes the changed threshold is in ``objects``, so the estimate stays below it.
        """
        if self._sigma is None:
            return
        # Sigmas in 8-bit bins of TAIL_MAX_SIGMAS / 256 (the last one holds everything beyond); objects' pixels
        # are put in bin 0, which is never above any bin.
        z = cv2.convertScaleAbs(diff / self._sigma, alpha=TAIL_BINS / TAIL_MAX_SIGMAS)
        n = diff.size
        if objects is not None:
            z = cv2.bitwise_and(z, cv2.bitwise_not(objects))
            n -= cv2.countNonZero(objects)
        if n * WEAK_FALSE_RATE < TAIL_MIN_PX:
            return
        k = _tail_bin(z, WEAK_FALSE_RATE * n, self._tail_bin)
        self._tail_bin = k
        level = (k + 0.5) * TAIL_MAX_SIGMAS / TAIL_BINS
        prev = self.tail_sigmas
        self.tail_sigmas = level if prev is None else prev + alpha * (level - prev)

    def _update_colour(self, objects: Mask | None, alpha: float) -> None:
        now = self._colour_now
        if self._colour_bg is None or now is None or now.small_shape != self._colour_bg.shape[:2]:
            return
        self._bg_spread = None
        # Only the rows the shadow test reads (the rest of the colour background is never read).
        h, w = self._colour_bg.shape[:2]
        r0, r1 = self._colour_rows[0], min(self._colour_rows[1], h)
        if r1 <= r0:
            return
        colour = now.small if (r0, r1) == (0, h) else now.small_box(0, r0, w, r1 - r0)
        learnt = self._colour_bg[r0:r1]
        if objects is None:
            cv2.accumulateWeighted(colour, learnt, alpha)
            return
        small_objects = cv2.resize(cv2.dilate(objects, _K5), (w, h), interpolation=cv2.INTER_NEAREST)
        cv2.accumulateWeighted(colour, learnt, alpha, mask=cv2.bitwise_not(small_objects[r0:r1]))


WARM_SLACK_NS = 2_000_000
"""Warm-up samples fall due this early (2 ms): a frame stamped with jitter just before its slot still counts."""

MAD_TO_SIGMA = 1.4826
"""Median absolute deviation -> standard deviation of Gaussian noise."""

MIN_SIGMA = 0.5
"""Least noise sigma (grey levels) a pixel is given: 8-bit quantisation alone is about 0.3."""

WEAK_FALSE_RATE = 1e-4
"""Fraction of the background's pixels whose difference may pass the joining threshold (the level of the noise
tail that :attr:`BackgroundModel.tail_sigmas` measures). Lower: hysteresis joins less, on clean images too;
higher: noise beside people joins them (their boxes grow on compressed video)."""

HYSTERESIS_CELL_PX = 2
"""Side of the cells on which hysteresis judges connectivity (:func:`_hysteresis`)."""

TAIL_MIN_PX = 4.0
"""Least expected number of background pixels beyond the tail level for a measurement of it to count."""

TAIL_BINS = 256
TAIL_MAX_SIGMAS = 32.0
"""Histogram of the background's differences in sigmas: bins over [0, TAIL_MAX_SIGMAS), one per 8-bit level."""

DEV_STEP = 1.0
"""Largest relative rise of a pixel's deviation from one update sample (1: it may double)."""

EGO_SECTORS = 36
"""Column sectors (10 degrees each on a panorama) of the camera-motion test."""

EGO_SECTOR_PX = 10
"""Moving pixels that make a sector count as moving in the camera-motion test."""

MIN_LIGHT_STEP = 0.04
"""A global gain closer to 1 than this is no light change: the abnormal change is the view itself."""

NEAR_SATURATION = 230
"""Grey level above which a rescaled background nears saturation: its colour channels clip one by one, so the
grey level is no longer the old one times the gain."""

DARK_GREY = 16
"""Background grey level at or below which a brightness ratio is mostly noise (dark pixels): no gain is read
there."""

CLIPPED_GREY = 250
"""Frame grey level at or above which the camera clips: the pixel's brightness ratio understates the gain."""

BLACK_GREY = 4
"""Frame grey level at or below which a pixel is black (the sensor's floor): no ratio for the global gain."""

GAIN_MIN_PX = 16
"""Fewest usable pixels of the sampled grid for a global gain (fewer: the gain is taken as 1)."""

LUT_ENTRIES = 256
"""Entries of an 8-bit lookup table (``cv2.LUT``): labels below it are mapped through one."""

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


def _hysteresis(strong: Mask, weak: Mask) -> Mask:
    """``strong`` and the pixels of ``weak`` connected to it through ``weak``, but for those touching ``strong``
    (``weak`` holds ``strong``: a lower threshold).

    Connectivity is judged on 2 x 2 cells (a cell is weak or strong if any of its pixels is): the labelling
    costs a quarter, and a faint part one pixel from a contrasted one is still the same object.

    The ring of pixels touching ``strong`` is left to the clean-up's majority vote: along the edge of
    something contrasted it is the partly covered fringe (blur), with the object on one side only, and
    stays out, as it would without hysteresis; between the contrasted part and a faint one (hair and a face
    of the wall's grey) both sides are set and the vote fills it.
    """
    height, width = weak.shape
    size = (max(1, width // HYSTERESIS_CELL_PX), max(1, height // HYSTERESIS_CELL_PX))
    weak_cells = cv2.resize(weak, size, interpolation=cv2.INTER_AREA)
    strong_cells = cv2.resize(strong, size, interpolation=cv2.INTER_AREA)
    # 16-bit labels where they fit (at most one region per 2 x 2 block of cells): labelling, gathering and
    # converting them cost less than 32-bit ones.
    fits = ((size[0] + 1) // 2) * ((size[1] + 1) // 2) < np.iinfo(np.uint16).max
    n, labels = cv2.connectedComponents(weak_cells, connectivity=8, ltype=cv2.CV_16U if fits else cv2.CV_32S)
    seeded = np.zeros(max(n, LUT_ENTRIES), np.uint8)
    seeded[labels[strong_cells > 0]] = 255
    seeded[0] = 0
    cell = HYSTERESIS_CELL_PX
    if (cell * size[0], cell * size[1]) == (width, height):
        # Each cell is a block of the image: ``weak`` without the blocks of its regions that hold no strong
        # cell (a few specks of noise), cleared in place -- scaling the seeded cells back up and masking
        # costs several times more.
        lone = 255 - seeded
        lone[0] = 0
        joined = weak.copy()
        # The labels' cells through an 8-bit lookup table where the labels fit (numpy's gather costs 5x);
        # not looked for when every region is seeded.
        if lone[1:n].any():
            lone_cells = cv2.LUT(cv2.convertScaleAbs(labels), lone[:LUT_ENTRIES]) if n <= LUT_ENTRIES else lone[labels]
            # Their blocks cleared within the lone cells' box (finding a few cells in the whole image, or
            # scaling all of it up, costs several times more).
            x, y, w, h = cv2.boundingRect(lone_cells)
            up = cv2.resize(lone_cells[y : y + h, x : x + w], (w * cell, h * cell), interpolation=cv2.INTER_NEAREST)
            box = joined[y * cell : (y + h) * cell, x * cell : (x + w) * cell]
            box[...] = cv2.subtract(box, up)
    else:
        cells = cv2.LUT(cv2.convertScaleAbs(labels), seeded[:LUT_ENTRIES]) if n <= LUT_ENTRIES else seeded[labels]
        joined = cv2.bitwise_and(cv2.resize(cells, (width, height), interpolation=cv2.INTER_NEAREST), weak)
    beyond = cv2.subtract(joined, cv2.dilate(strong, _K3))  # faint parts, not touching the contrasted ones
    # strong | beyond | ring, where the ring is what of ``joined`` touches both ``strong`` and ``beyond``:
    # ``beyond`` lies inside its own dilation and ``strong`` inside ``joined``, so ``joined`` where that
    # dilation is and ``strong`` elsewhere.
    out = strong.copy()
    cv2.copyTo(joined, cv2.dilate(beyond, _K3), out)
    return out


def _rows_read(floor: Mask | None, height: int) -> tuple[int, int]:
    """Rows [r0, r1) of a reduced colour image the shadow test reads for this ``floor``: the floor's rows and
    the texture window's reach beyond them (all rows without a floor)."""
    if floor is None:
        return 0, height
    _, y, _, h = cv2.boundingRect(floor)
    if h == 0:
        return 0, 0
    m = TEXTURE_WINDOW // 2
    return max(y - m, 0), min(y + h + m, height)


def _tail_bin(z: Mask, limit: float, hint: int | None) -> int:
    """The first bin k of ``z`` (8-bit bins 0 .. ``TAIL_BINS`` - 1) with at most ``limit`` pixels above it.

    Found by counting the pixels above a few bins, from ``hint`` (the last update's bin: the tail moves
    little between updates) outwards, then by halving: a threshold and a count each cost a small fraction
    of a histogram of the panorama (slow on such images, mostly of a few low bins). The counts are compared
    as 32-bit floats, as a histogram's cumulative counts were.
    """
    lim = np.float32(limit)

    def few_above(k: int) -> bool:
        return bool(np.float32(cv2.countNonZero(cv2.threshold(z, k, 255, cv2.THRESH_BINARY)[1])) <= lim)

    last = TAIL_BINS - 1  # nothing is above the last bin's level: it always qualifies
    k = min(max(hint if hint is not None else TAIL_BINS // 8, 0), last)
    # Bracket: ``bad`` does not qualify (or is -1), ``good`` does.
    if few_above(k):
        good, step = k, 1
        bad = good - step
        while bad >= 0 and few_above(bad):
            good, step = bad, 2 * step
            bad = good - step
        bad = max(bad, -1)
    else:
        bad, step = k, 1
        good = bad + step
        while good < last and not few_above(good):
            bad, step = good, 2 * step
            good = bad + step
        good = min(good, last)
    while good - bad > 1:
        mid = (bad + good) // 2
        if few_above(mid):
            good = mid
        else:
            bad = mid
    return good


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
    usable = (b > DARK_GREY) & (g < CLIPPED_GREY)
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
    ok = (b > DARK_GREY) & (g > BLACK_GREY) & (g < CLIPPED_GREY)
    if int(np.count_nonzero(ok)) < GAIN_MIN_PX:
        return 1.0
    return float(np.median(g[ok] / b[ok]))
