"""Stage 2b: still regions of the background model -- ghosts absorbed, people who pause kept.

Used by :class:`sensor_node.background.model.BackgroundModel` on every normal frame. A
*ghost* -- something that was in the background and left (a person who stood
still while the model learnt) -- changes pixels like a person does but never
moves. :class:`StillRegions` counts, per pixel, the frames it has been
changed-but-still and tests the regions that stayed so for ``ghost_frames``:
a ghost's outline is an edge of the background image but not of the current
frame (where the wall is smooth), a paused person's outline the reverse.
Ghosts are copied into the background; people who stand still are kept while
they stand (their outline is an edge of the frame, not of the model) up to
``still_keep_frames`` -- a ghost revealing a contrasted background (a white
post where someone stood) passes that test too and must not stay for ever; a
still region that neither test recognises (on a textured floor) becomes
background after ``still_absorb_frames``, so no ghost stays.

The surface beside a region is a second test (:func:`~sensor_node.background.ghosts.surround_deviation`):
a region changed ever since the model was young (*born*) is a start-up hole unless the frame,
not the model, clearly departs from the surface beside it (:func:`~sensor_node.background.ghosts.start_up_hole`),
absorbed at its first test whatever its outline says (a plain shirt before a textured wall; a
grey shirt held where the frame shows a bright ceiling corner), and tested from its first still
sample (``ghost_frames`` is the outline test's wait). Someone walking out of their own hole is
beside it for a while, one region with it: there the hole's columns go
(:func:`~sensor_node.background.ghosts.hole_columns`) and they stay. An outline "ghost" whose frame
is no closer to its surroundings than the model is, is not absorbed. What an absorption
overwrote (outside start-up holes) is kept a while and put back where the frame shows it again
(:class:`~sensor_node.background.ghosts.UnderGhosts`).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np
import numpy.typing as npt

from common.arrays import Float32Array, Mask
from sensor_node.background.ghosts import UnderGhosts, hole_columns, start_up_hole, surround_deviation
from sensor_node.components import ColumnRuns, components
from sensor_node.config import PipelineSettings

__all__ = ["BORN_FRAMES", "STATIC_EVERY", "StillRegions"]

logger = logging.getLogger(__name__)


STATIC_EVERY = 4
"""Frames between samples of the changed-but-still counter (ghost detection)."""

BORN_FRAMES = 30
"""Normal frames (2 s at 15 fps) after the model is learnt during which someone who stood in the view while
it was learnt can walk off and leave a start-up hole (pixels that turn changed during them and stay so)."""

GHOST_EDGE = 10.0
"""Least mean edge strength (grey levels, 3x3 morphological gradient) of a ghost's outline in the background."""

GHOST_SCORE = 2.5
"""Background-outline / frame-outline edge ratio above which a still region is a ghost (people: < 1)."""

GHOST_RING_CHANGED = 0.35
"""Fraction of the 4-px ring around a still region that may be changed for it to be absorbed as a ghost."""

PERSON_SCORE = 1.5
"""Frame-outline / background-outline edge ratio above which a still region is a paused object, kept."""

CLOSE_REACH_PX = 4
"""Margin around the still pixels within which the 5 x 5 closing can change or consult pixels."""

SOLID_FRAC = 0.3
"""Least fraction of its box a still region fills for an outline test: below it, a speck or a sliver of an
absorbed ghost's edge, whose outline would be ragged."""

BORN_SHARE = 0.5
"""Fraction of a still region's pixels that must be born (changed since the model was young) for the region
to count as born."""

MAX_SAMPLES = 254
"""Largest wait in samples of the changed-but-still counter: it is 8-bit and saturates at 255."""

_K3 = np.ones((3, 3), np.uint8)
_K5 = np.ones((5, 5), np.uint8)
_K9 = np.ones((9, 9), np.uint8)


@dataclass(frozen=True, slots=True)
class _Waits:
    """The still-region tests' waits, in samples of the changed-but-still counter."""

    samples: int
    """``ghost_frames``: still this long, a region is tested (a born one from its first sample)."""
    long_still: int
    """``still_absorb_frames``: still this long, what no test recognises becomes background."""
    keep_still: int
    """``still_keep_frames``: still this long, a paused person is no longer kept."""

    @classmethod
    def of(cls, s: PipelineSettings) -> _Waits:
        samples = max(1, min(MAX_SAMPLES, -(-s.ghost_frames // STATIC_EVERY)))
        long_still = max(samples, min(MAX_SAMPLES, -(-s.still_absorb_frames // STATIC_EVERY)))
        keep_still = max(long_still, min(MAX_SAMPLES, -(-s.still_keep_frames // STATIC_EVERY)))
        return cls(samples, long_still, keep_still)


@dataclass(frozen=True, slots=True)
class _Sample:
    """One sampling frame as the still-region tests read it."""

    grey: Mask
    """The frame."""
    fg: Mask
    """Its changed pixels (255) against the model."""
    moved: Mask
    """Its moving pixels (frame differencing)."""
    bg: Float32Array
    """The float model, absorbed into in place."""
    bg_u8: Mask
    """The model as 8-bit grey levels before this frame's absorptions."""
    frame: int
    """The model's frame count."""


def _mostly(born: Mask, origin: tuple[int, int], sel: npt.NDArray[np.bool_], n: int) -> bool:
    """Whether ``BORN_SHARE`` of the ``n`` pixels ``sel`` (in their box at ``origin``) are set in ``born``."""
    x, y = origin
    h, w = sel.shape
    return bool(np.count_nonzero(born[y : y + h, x : x + w][sel]) >= BORN_SHARE * n)


def _outline_edges(
    grey: Mask, bg_u8: Mask, mask: npt.NDArray[np.bool_], origin: tuple[int, int]
) -> tuple[float, float, int]:
    """The edge strength (3 x 3 morphological gradient) summed along a still region's outline in the model and
    in the frame, and the outline's length in pixels (at least 1)."""
    x, y = origin
    h, w = mask.shape
    outline = cv2.morphologyEx(mask.astype(np.uint8), cv2.MORPH_GRADIENT, _K3) > 0
    cur = cv2.morphologyEx(grey[y : y + h, x : x + w], cv2.MORPH_GRADIENT, _K3)
    was = cv2.morphologyEx(bg_u8[y : y + h, x : x + w], cv2.MORPH_GRADIENT, _K3)
    was_sum, n_out = float(was[outline].sum()), max(1, int(np.count_nonzero(outline)))
    cur_sum = float(cur[outline].sum())
    return was_sum, cur_sum, n_out


def _closed_regions(old: Mask) -> tuple[int, Mask, npt.NDArray[np.int32], list[int], int]:
    """The regions of the still pixels ``old`` after a 5 x 5 closing: their count (with the background's
    label 0), labels, statistics (:func:`~sensor_node.components.components`', in image coordinates), each
    one's first column in the labels, and the labels' first image row.

    The still pixels are a few regions of a large image, often far apart: the closing and the labelling
    work on the box around them (with the closing's reach), and in it on the columns that hold them only
    (:class:`~sensor_node.components.ColumnRuns`, with a margin beyond the closing's reach: every region
    and its closing stay as they are).
    """
    bx, by, bw, bh = cv2.boundingRect(old)
    x0, y0 = max(bx - CLOSE_REACH_PX, 0), max(by - CLOSE_REACH_PX, 0)
    x1, y1 = min(bx + bw + CLOSE_REACH_PX, old.shape[1]), min(by + bh + CLOSE_REACH_PX, old.shape[0])
    box = old[y0:y1, x0:x1]
    runs = ColumnRuns(box, CLOSE_REACH_PX + 1)
    n, labels, stats = components(cv2.morphologyEx(runs.pack(box) if runs.apart else box, cv2.MORPH_CLOSE, _K5))
    label_x = [0, *stats[1:, 0].tolist()]
    for k in range(1, n):
        stats[k, 0] = x0 + (runs.unpack(label_x[k]) if runs.apart else label_x[k])
    stats[1:, 1] += y0
    return n, labels, stats, label_x, y0


class StillRegions:
    """The changed-but-still regions of one learnt background model (a new one after each re-learning).

    Args:
        settings: the ``[pipeline]`` knobs (``ghost_frames``, ``still_absorb_frames``, ``still_keep_frames``,
            ``min_blob_px``, ``fg_threshold``).
    """

    def __init__(self, settings: PipelineSettings) -> None:
        self.settings = settings
        self._born_age = 0
        """Normal frames seen since the model was learnt."""
        self._static: Mask | None = None
        self._born: Mask | None = None
        """Changed pixels that have stayed changed since the model was learnt, or since they turned changed
        during its first ``BORN_FRAMES`` normal frames: where a start-up hole can be."""
        self._born_first: Mask | None = None
        """Changed pixels that have stayed changed since the model was learnt: someone who came in later
        cannot be among them."""
        self._born_live = self._born_first_live = True
        """The born masks may still hold changed pixels (an emptied one stays so, once the model is no longer
        young)."""
        self._last_fg: Mask | None = None
        """The last frame's changed pixels, while the model is young."""
        self._under: UnderGhosts | None = None
        """The model from under absorbed ghosts: put back where the frame shows it again (a mistake)."""
        self.ghosts = 0
        """Ghost blobs (objects that left the background) absorbed."""
        self.kept = 0
        """Still-region tests that found a paused object (its outline in the frame) and kept it."""
        self.restored = 0
        """Regions of the model under an absorbed ghost put back (the frame showed them again: a mistake)."""

    def reset(self) -> None:
        """Forget every region (the model is learnt afresh); the counters go on."""
        self._born_age = 0
        self._static = self._born = self._born_first = self._last_fg = None
        self._under = None

    def forget_under(self) -> None:
        """Drop what absorptions overwrote (the model was rescaled by a light change: it no longer fits)."""
        self._under = None

    def update(
        self, grey: Mask, fg: Mask, moving: Callable[[], Mask], *, bg: Float32Array, bg_u8: Mask, frame: int
    ) -> bool:
        """Follow one normal frame; absorb ghosts into ``bg`` (in place). True if ``bg`` changed.

        Args:
            grey: the frame.
            fg: its changed pixels (255) against the model.
            moving: its moving pixels (frame differencing), computed when first called: only the sampling
                frames (every ``STATIC_EVERY``-th) read them.
            bg: the float model, updated in place.
            bg_u8: the model as 8-bit grey levels before this frame's changes.
            frame: the model's frame count (sampling and the age of what absorptions overwrote).
        """
        self._follow_born(fg)
        # Sampled every STATIC_EVERY frames (cheap; ghosts are not urgent): the counter counts samples.
        if frame % STATIC_EVERY:
            return False
        # A born mask that emptied stays empty (past the model's youth each frame can only clear more of it):
        # no more ANDs.
        assert self._born is not None and self._born_first is not None  # set by _follow_born
        self._born_first_live = self._born_first_live and cv2.countNonZero(self._born_first) > 0
        self._born_live = self._born_live and cv2.countNonZero(self._born) > 0
        moved = moving()
        still = cv2.bitwise_and(fg, cv2.bitwise_not(moved))
        if self._static is None:
            self._static = np.zeros_like(grey)
        self._static = cv2.bitwise_and(cv2.add(self._static, 1, mask=still), still)  # type: ignore[call-overload, unused-ignore]
        changed = False
        if self._under is not None and self._under.expired(frame):
            self._under = None  # everything it kept is too old to put back
        if self._under is not None:
            s = self.settings
            back, regions = self._under.restore(
                grey, still, bg, frame=frame, match_level=s.fg_threshold, least_px=s.min_blob_px
            )
            self.restored += regions
            if back is not None:
                self._static[back > 0] = 0
                bg_u8 = cv2.convertScaleAbs(bg)
                changed = True
        waits = _Waits.of(self.settings)
        old = cv2.threshold(self._static, waits.samples - 1, 255, cv2.THRESH_BINARY)[1]
        if self._born is not None and self._born_live:
            # A born region is tested from its first still sample: the surface beside it tells a start-up
            # hole from someone who stands (start_up_hole) without waiting for an outline to settle; a
            # hole left as a blob meanwhile is reported as someone standing where they stood. (An emptied
            # born mask, most of a model's life, adds nothing.)
            cv2.bitwise_or(old, cv2.bitwise_and(self._born, still), dst=old)
        if cv2.countNonZero(old) == 0:
            return changed
        # Whole regions, not the speckle of their flat insides: a ghost test on a ragged outline
        # would measure texture, not the silhouette.
        n, labels, stats, label_x, y0 = _closed_regions(old)
        at = _Sample(grey, fg, moved, bg, bg_u8, frame)
        for k in range(1, n):
            x, y, w, h, area = (int(v) for v in stats[k])
            mask = labels[y - y0 : y - y0 + h, label_x[k] : label_x[k] + w] == k
            if self._test_region(at, mask, (x, y), area=area, waits=waits):
                changed = True
        return changed

    def _follow_born(self, fg: Mask) -> None:
        """Follow the born masks by one normal frame's changed pixels ``fg``.

        Born: changed ever since the model was learnt. Someone standing in the view while it was learnt is in
        the model, and their hole opens only as they walk off: what turns changed during the model's first
        ``BORN_FRAMES`` and stays so counts too (not what changed meanwhile and left).
        """
        self._born_age += 1
        if self._born is None or self._born_first is None:
            self._born, self._born_first = fg.copy(), fg.copy()
            self._born_live = self._born_first_live = True
        else:
            if self._born_first_live:
                cv2.bitwise_and(self._born_first, fg, dst=self._born_first)
            if self._born_age <= BORN_FRAMES and self._last_fg is not None:
                # While the model is young, a pixel that turns changed and stays so may be a hole opening:
                # the part of someone in the model that they covered in the frame too until they moved.
                cv2.bitwise_or(self._born, cv2.bitwise_not(self._last_fg), dst=self._born)
                self._born_live = True
            if self._born_live:
                cv2.bitwise_and(self._born, fg, dst=self._born)
        self._last_fg = fg.copy() if self._born_age < BORN_FRAMES else None

    def _test_region(
        self, at: _Sample, mask: npt.NDArray[np.bool_], origin: tuple[int, int], *, area: int, waits: _Waits
    ) -> bool:
        """Test one still region (``mask``, of ``area`` pixels, in its box at ``origin`` = (column, row)) and
        absorb what of it is a ghost, a start-up hole or has stood too long. True if ``bg`` changed."""
        assert self._static is not None
        grey, fg, bg_u8 = at.grey, at.fg, at.bg_u8
        x, y = origin
        h, w = mask.shape
        age = int(self._static[y : y + h, x : x + w][mask].max())
        if area < self.settings.min_blob_px or area < SOLID_FRAC * w * h:
            # Too small or too ragged for an outline test: becomes background after still_absorb_frames.
            return age >= waits.long_still and self._absorb_fragment(at, mask, origin, area)
        was_sum, cur_sum, n_out = _outline_edges(grey, bg_u8, mask, origin)
        score = was_sum / (cur_sum + 1.0)
        # A ghost's outline is a real silhouette edge in the background (not two flat surfaces
        # whose ratio is noise: the still inside of a slowly walking person's shirt).
        ghost = score >= GHOST_SCORE and was_sum / n_out >= GHOST_EDGE
        # The surface beside the region decides too: a hole shows in the frame what continues on
        # both sides, while the model holds the one who left. It overrules the outline test when
        # the frame is no closer to the surroundings than the model is (someone standing in front
        # of a window: its frame is a strong outline of the model, but that is no ghost).
        born = self._born is not None and self._born_live and _mostly(self._born, origin, mask, area)
        # Neither an outline ghost nor a start-up hole: no surround can make it one (not computed).
        dev_cur, dev_bg = surround_deviation(grey, bg_u8, fg, mask, origin) if ghost or born else (0.0, 0.0)
        hole = born and dev_cur + dev_bg > 0.0 and start_up_hole(dev_cur, dev_bg)
        # Changed since the model was learnt, the model holds whoever stood there: nothing to put
        # back. Changed since the end of its first BORN_FRAMES only, it may be someone who came in
        # meanwhile and stands (in front of a window, looking like its hole): keep what was there.
        first = hole and self._born_first is not None and _mostly(self._born_first, origin, mask, area)
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
        if born and not ghost:
            # Someone who stood while the model was learnt walks out of their hole: the hole's
            # columns are absorbed now, the one beside them is tested again later.
            part = mask & hole_columns(grey, bg_u8, fg, mask, origin)[None, :]
            if int(np.count_nonzero(part)) >= self.settings.min_blob_px:
                return self._absorb_hole(at, origin, part=part, beside=mask)
        if age < waits.samples and not hole:
            return False  # still too briefly for any test but the start-up hole's
        if not ghost:
            # A paused person is the reverse: the silhouette is an edge of the current frame, not of
            # the background. They stay an object region (never learnt) however long they stand;
            # only what neither test recognises becomes background after still_absorb_frames.
            if cur_sum >= PERSON_SCORE * (was_sum + 1.0) and cur_sum / n_out >= GHOST_EDGE and age < waits.keep_still:
                self.kept += 1
                return False
            if age < waits.long_still:
                return False
        # Anything but a hole since the model was learnt may be a mistake -- a born region too:
        # someone in view since the model was young who stood still -- keep what was there.
        absorbed = self._absorb(at, mask, origin, keep=not first)
        if absorbed:
            logger.debug("ghost of %d px at column %d absorbed (edge score %.2f)", area, x, score)
        return absorbed

    def _absorb_fragment(self, at: _Sample, mask: npt.NDArray[np.bool_], origin: tuple[int, int], area: int) -> bool:
        """Absorb a still region too small or too ragged for an outline test. True if ``bg`` changed.

        A speck, or a sliver of a ghost's edge left by an absorption (the model there still holds the
        person's outline, a few grey levels over the threshold). Changed pixels are never learnt, so it would
        stay for ever and join the blob of whoever passes it: it becomes background after
        ``still_absorb_frames`` too, unless changed pixels surround it (part of someone). What it overwrote is
        kept: the part of someone that alone differs from the wall (a shirt of the wall's grey in front of a
        poster) comes back when they walk on.
        """
        absorbed = self._absorb(at, mask, origin, keep=True, fringe=False)
        if absorbed:
            logger.debug("still fragment of %d px at column %d absorbed", area, origin[0])
        return absorbed

    def _absorb_hole(
        self, at: _Sample, origin: tuple[int, int], *, part: npt.NDArray[np.bool_], beside: npt.NDArray[np.bool_]
    ) -> bool:
        """Absorb the hole's columns ``part`` of a born region ``beside`` (the rest of it is whoever walks out of
        the hole, kept out of the absorption's ring). True if ``bg`` changed."""
        n_part = int(np.count_nonzero(part))
        first_part = self._born_first is not None and _mostly(self._born_first, origin, part, n_part)
        absorbed = self._absorb(at, part, origin, keep=not first_part, fringe=False, beside=beside)
        if absorbed:
            logger.debug("hole of %d px beside someone at column %d absorbed", n_part, origin[0])
        return absorbed

    def _absorb(
        self,
        at: _Sample,
        mask: npt.NDArray[np.bool_],
        origin: tuple[int, int],
        *,
        keep: bool,
        fringe: bool = True,
        beside: npt.NDArray[np.bool_] | None = None,
    ) -> bool:
        """Copy a still region (``mask`` in its box at ``origin`` = (column, row)) of the frame into the model.

        With ``fringe``, the ghost's fringe too: its changed, not moving pixels up to 4 px around the
        region (not the edge of someone walking past it); without, the region's own not moving pixels
        only (a fragment: what is around it may be someone whose rest matches the wall). Not if the
        region continues into changed pixels all around (``GHOST_RING_CHANGED``). ``keep``: remember the model it
        overwrote (:class:`UnderGhosts`). ``beside`` (the box's shape): pixels known to be someone next to
        the region, not counted in that ring. Returns whether it was absorbed into ``bg``.
        """
        assert self._static is not None
        grey, fg, moving, bg, frame = at.grey, at.fg, at.moved, at.bg, at.frame
        x, y = origin
        h, w = mask.shape
        y0, y1, x0, x1 = max(0, y - 4), min(grey.shape[0], y + h + 4), max(0, x - 4), min(grey.shape[1], x + w + 4)
        region = np.zeros((y1 - y0, x1 - x0), np.uint8)
        region[y - y0 : y - y0 + h, x - x0 : x - x0 + w][mask] = 255
        grown = cv2.dilate(region, _K9) > 0
        ring = grown & (region == 0)
        if beside is not None:
            ring[y - y0 : y - y0 + h, x - x0 : x - x0 + w] &= ~beside
        around = np.count_nonzero(ring & (fg[y0:y1, x0:x1] > 0))
        if around > GHOST_RING_CHANGED * np.count_nonzero(ring):
            # A ghost is the whole changed region (beyond it the frame matches the model); this one
            # continues into changed pixels all around: the still inside of someone walking (a
            # uniform shirt does not change from frame to frame). Learning it would paint them in.
            return False
        take = (grown & (fg[y0:y1, x0:x1] > 0) if fringe else region > 0) & (moving[y0:y1, x0:x1] == 0)
        sub = bg[y0:y1, x0:x1]
        if keep:
            if self._under is None:
                self._under = UnderGhosts(grey.shape)
            self._under.keep((x0, y0), take, sub, frame)
        sub[take] = grey[y0:y1, x0:x1][take]
        self._static[y0:y1, x0:x1][take] = 0
        self.ghosts += 1
        return True
