"""The tracker's model of people and cameras, in physical units: every number the track stages use.

:class:`TrackModel` *is* the ``[tracker]`` table of the manager's config: each knob is declared, documented and
defaulted here once, and the config file reads it as it is (``resource_manager.config``). None of them is a
frame count: the same values serve cameras at 2 fps and at 30 fps. :class:`Scene` holds what the tracker knows
of the site itself (where people can be, how far the cameras see), which is not tuning.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Annotated, Literal

import msgspec

from common.area import Floor
from common.config import ConfigStruct

__all__ = ["HEAD_HEIGHT_M", "HEAD_HEIGHT_SIGMA_M", "PERSON_RADIUS_M", "Scene", "TrackModel", "logit"]

PERSON_RADIUS_M = 0.25
"""Half the width of a person seen from any side (m): who hides whom, and how far apart two people stand."""
HEAD_HEIGHT_M = 1.7
"""Head-top height of a person before any view measured it (m): the default of ``[tracker] height_prior_m``."""
HEAD_HEIGHT_SIGMA_M = 0.15
"""Spread of people's head-top heights around it (m): the default of ``[tracker] height_sigma_m``."""

Pos = Annotated[float, msgspec.Meta(gt=0.0)]
NonNeg = Annotated[float, msgspec.Meta(ge=0.0)]
Prob = Annotated[float, msgspec.Meta(gt=0.0, lt=1.0)]


def logit(p: float) -> float:
    """ln(p / (1 - p))."""
    return math.log(p / (1.0 - p))


class TrackModel(ConfigStruct, frozen=True):
    """``[tracker]``: how people move, how cameras see them, and how sure the tracker must be."""

    mode: Literal["model", "paper"] = "model"
    """``model``: each track is updated with every view assigned to it (bearing, feet distance), each with its
    own covariance. ``paper``: with the best pair of those views by the error model (Eq. 1 or Eq. 2)."""
    speed_sigma_mps: Pos = 0.8
    """Spread of a walker's velocity along each axis (a standing person's is 0). Raising it follows turns and
    starts faster, lowering it smooths more."""
    turn_time_s: Pos = 2.0
    """How long a walker keeps a velocity: the motion model's velocity decays to 0 over this time (people
    stop, turn and start), so a person nobody sees is predicted to stay near where they were last seen."""
    max_speed_mps: Pos = 2.5
    """Nobody walks faster than this: how far a person who went unseen can have gone (a brisk walk; raise it
    for a site where people run)."""
    body_sigma_m: Pos = 0.1
    """Spread of the point a camera sees (head, box bottom centre) around the person's floor position, for a
    sensor whose SensorInfo does not state its own (``point_sigma_m``)."""
    outlier_prob: Annotated[float, msgspec.Meta(gt=0.0, lt=0.5)] = 0.05
    """Share of detections whose point is off by several sigmas (a badly drawn box, someone bending)."""
    outlier_scale: Annotated[float, msgspec.Meta(gt=1.0)] = 4.0
    """How many times wider the spread of those outliers is."""
    feet_hidden_prob: Annotated[float, msgspec.Meta(ge=0.0, lt=1.0)] = 0.02
    """Probability that a perspective camera's box bottom is not the feet although nobody is predicted in front
    (furniture, a bag): a box cut above the feet puts the person farther than they are, so such a distance is
    discounted, not trusted. (A box whose top then puts the head at no person's height gives no distance at all:
    :mod:`resource_manager.views.mono`.)"""
    feet_cut_prob_covered: Annotated[float, msgspec.Meta(ge=0.0, lt=1.0)] = 0.5
    """...and that it is not, for a person whose feet someone nearer or another camera's body hides in the picture
    (in between: by the share of the feet hidden): a detector that boxes what it sees cuts them there; an
    annotator's box reaches the feet behind anyone."""
    height_prior_m: Pos = HEAD_HEIGHT_M
    """Head-top height of a person before any view measured it (also where the planner and the PTZ cameras
    aim at a track whose height is unknown)."""
    height_sigma_m: Pos = HEAD_HEIGHT_SIGMA_M
    """Spread of people's heights around ``height_prior_m``."""
    height_change_mps: Pos = 0.05
    """How fast a person's head-top height changes (bending, sitting)."""
    height_range_m: Pos = 2.5
    """Heights a false detection may imply, uniformly: the clutter's height density is 1/this."""
    p_detect: Prob = 0.9
    """Probability that a camera detects a person in its picture whom nobody hides."""
    p_detect_hidden: Annotated[float, msgspec.Meta(ge=0.0, lt=1.0)] = 0.3
    """...and a person wholly covered in the picture by people nearer to the camera (in between: by the share
    of their silhouette that shows). A miss where detection was not expected costs the track little."""
    clutter_per_view: Pos = 1.0
    """Expected false detections per view and frame, spread uniformly over its field of view and range. Raising
    it asks more evidence of people."""
    evidence_time_s: Pos = 0.5
    """A view's detections within this time of each other are one piece of evidence (a person hidden or a
    false detection persists over successive frames): existence moves at most one view's worth per this.
    Raising it confirms and ends tracks more slowly."""
    birth_confidence: Annotated[float, msgspec.Meta(ge=0.0, le=1.0)] = 0.5
    """A blob less sure than this (a detector's score, a panoramic node's head cut by the picture's top) may
    update a track but never starts one."""
    p_birth: Prob = 0.1
    """Prior probability that unexplained detections that agree across views are a new person."""
    p_confirm: Prob = 0.9
    """A track is published once its existence probability reaches this."""
    p_delete: Prob = 0.1
    """A track whose existence probability falls below this ends."""
    p_max: Prob = 0.99
    """Existence probability is held below this where a person can leave (at an exit of the site's area, or
    anywhere when the site declares none), so that someone who left ends within a few missed views."""
    p_max_inside: Prob = 0.9999
    """...and below this inside a declared area, away from its exits: a person there cannot have gone, so a
    track survives more missed views (someone hidden in a crowd) before it ends."""
    publish_sigma_m: Pos = 2.0 * PERSON_RADIUS_M
    """A confirmed track is reported only while its position is known to within this (1 sigma, its worst
    direction): a person's width, beyond which it cannot tell two people side by side apart (one view's bearing
    alone, or a pair of views near colinear, leaves a position that vague along the ray). Until its views pin
    it down again it is held, with its id, unreported. Raising it reports vaguer positions."""
    lost_sigma_m: Pos = 2.0
    """A track whose position is this uncertain (1 sigma, its worst direction) has lost its person: it ends."""
    apart_time_s: Pos = 1.0
    """Two published tracks that the views have shown as two people (their blobs, one to each, over time) are taken
    for one person followed twice only after standing together, never told apart, this long: two people side by
    side hide each other from the views for a moment and are then seen apart again (the tracks of two people pulled
    onto one spot by a moment's wrong blobs must not be merged into one), while one person followed twice stays so.
    Longer keeps more such pairs apart and publishes a person followed twice longer."""
    reid_window_s: NonNeg = 10.0
    """A confirmed track that ended inside the area (not through an exit), lost or taken for another track's
    person followed twice, is remembered this long: a new person who appears where it could have walked since, and
    whose height and colours agree, takes its id back (0: no re-identification)."""
    colour_sigma: Pos = 0.15
    """Spread of the Bhattacharyya distance between a person's blobs and their look in one view."""
    look_time_s: Pos = 2.0
    """Memory of a track's per-view colour look."""
    look_min_s: NonNeg = 0.5
    """A look learnt for less than this is not yet compared."""
    link_odds: Annotated[float, msgspec.Meta(ge=1.0)] = 4.0
    """How much likelier a blob that continues the node's 2D track of a person is theirs than another's."""
    gate_sigmas: Pos = 10.0
    """A blob further than this many sigmas (bearing or feet distance) from a track is not considered for it. The
    gate leaves the weighing to the likelihood, whose outlier part (``outlier_scale`` times wider) still gives a
    blob 10 sigmas off a chance (2.5 of its own sigmas): a track that fell behind its person, or whose person's
    box is badly drawn, keeps its person as a candidate instead of losing them to a new track."""

    @property
    def turn_rate(self) -> float:
        return 1.0 / self.turn_time_s


@dataclass(frozen=True, slots=True)
class Scene:
    """What the tracker knows of the site: where people can be, and how far its cameras see anyone."""

    area: Floor | None = None
    """The floor people can be in and its exits (None: unbounded, people come and go anywhere); a zone manager's:
    the part of it near its zone (:class:`common.area.NearZone`)."""
    max_range_m: float = 100.0
    """Cameras see nobody farther than this."""
