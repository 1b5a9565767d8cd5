"""The tracker's model of people and cameras, in physical units: every number the track stages use.

One place for the probabilities, times and lengths the tracker reasons with (``[tracker]`` and ``[match]`` in
the config, turned into these units by :mod:`resource_manager.wiring`). None of them is a frame count: the same
values serve cameras at 2 fps and at 30 fps.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

__all__ = ["PERSON_RADIUS_M", "TrackModel", "logit"]

PERSON_RADIUS_M = 0.25
"""Half the width of a person seen from any side (m): who hides whom, and how far apart two people stand."""


def logit(p: float) -> float:
    """ln(p / (1 - p))."""
    return math.log(p / (1.0 - p))


@dataclass(frozen=True, slots=True)
class TrackModel:
    """How people move, how cameras see them, and how sure the tracker must be (see ``[tracker]``)."""

    mode: Literal["model", "paper"] = "model"
    """``model``: each track is updated with every view assigned to it (bearing, feet distance), each with its
    own covariance. ``paper``: with the best pair of those views by the error model (Eq. 1 or Eq. 2)."""
    speed_sigma_mps: float = 0.8
    """Spread of a walker's velocity along each axis (a standing person's is 0)."""
    turn_time_s: float = 2.0
    """How long a walker keeps a velocity: the motion model's velocity decays to 0 over this time (people
    stop, turn and start), so a person nobody sees is predicted to stay near where they were last seen."""
    body_sigma_m: float = 0.1
    """Spread of the point a camera sees (head, box bottom centre) around the person's floor position, for a
    sensor whose SensorInfo does not state its own (``point_sigma_m``)."""
    outlier_prob: float = 0.05
    """Share of detections whose point is off by several sigmas (a badly drawn box, someone bending)."""
    outlier_scale: float = 4.0
    """How many times wider the spread of those outliers is."""
    height_prior_m: float = 1.7
    """Head-top height of a person before any view measured it."""
    height_sigma_m: float = 0.15
    """Spread of people's heights around ``height_prior_m``."""
    height_change_mps: float = 0.05
    """How fast a person's head-top height changes (bending, sitting)."""
    height_range_m: float = 2.5
    """Heights a false detection may imply, uniformly: the clutter's height density is 1/this."""
    p_detect: float = 0.9
    """Probability that a camera detects a person in its picture whom nobody hides."""
    p_detect_hidden: float = 0.3
    """...and a person wholly covered in the picture by people nearer to the camera (in between: by the share
    of their silhouette that shows)."""
    clutter_per_view: float = 1.0
    """Expected false detections per view and frame, spread uniformly over its field of view and range."""
    evidence_time_s: float = 0.5
    """A view's detections within this time of each other are one piece of evidence (a person hidden or a
    false detection persists over successive frames): existence moves at most one view's worth per this."""
    p_birth: float = 0.1
    """Prior probability that unexplained detections that agree across views are a new person."""
    p_confirm: float = 0.9
    """A track is published once its existence probability reaches this."""
    p_delete: float = 0.1
    """A track whose existence probability falls below this ends."""
    p_max: float = 0.99
    """Existence probability is held below this, so that a long-seen person who left ends in a few seconds."""
    publish_sigma_m: float = 2.0 * PERSON_RADIUS_M
    """A confirmed track is reported only while its position is known to within this (1 sigma, its worst
    direction): a person's width, beyond which it cannot tell two people side by side apart (one view's bearing
    alone, or a pair of views near colinear, leaves a position that vague along the ray)."""
    lost_sigma_m: float = 2.0
    """A track whose position is this uncertain (1 sigma, its worst direction) has lost its person: it ends."""
    colour_sigma: float = 0.15
    """Spread of the Bhattacharyya distance between a person's blobs and their look in one view."""
    look_time_s: float = 2.0
    """Memory of a track's per-view colour look."""
    look_min_s: float = 0.5
    """A look learnt for less than this is not yet compared."""
    link_odds: float = 4.0
    """How much likelier a blob that continues the node's 2D track of a person is theirs than another's."""
    room: tuple[float, float, float, float] | None = None
    """``(x0, y0, x1, y1)`` of the floor people can be in (None: unbounded)."""
    room_margin_m: float = 0.5
    """How far outside ``room`` a new person may still be started."""
    max_range_m: float = 100.0
    """Cameras see nobody farther than this."""
    gate_sigmas: float = 5.0
    """A blob further than this many sigmas (bearing or feet distance) from a track is not considered for it."""

    @property
    def turn_rate(self) -> float:
        return 1.0 / self.turn_time_s
