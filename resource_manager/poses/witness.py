"""Witnesses of a camera's position: no single one may move it.

Each camera ``o`` of known pose that sights robot ``t`` is a *witness*: its
sighting alone puts ``t`` at one place (range and bearing, Eq. 3). Sightings
arrive under their sender's own key, which only that camera's certificate may
publish on, so a witness is a sender: a stolen camera can lie in its own
sightings, and nowhere else.

:func:`consistent` keeps the witnesses that agree: an estimate further from the
weighted mean of the others than ``k`` times their joint sigma (plus a slack) is
refused, worst first, while at least two remain. Two that disagree are told
apart only by a reference (where ``t`` was held): the one further from it is
refused; with no reference both are kept (their mean is then checked against
``t``'s history by the solver, :mod:`resource_manager.poses.solver`).
:func:`blame` names the witnesses behind a position the solver refused.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

__all__ = ["SLACK_M", "Estimate", "blame", "combine", "consistent"]

SLACK_M = 0.05

PAIR_OF_WITNESSES = 2
"""Witnesses are checked against each other from two on; between just two that disagree, only a reference (where
the target was held) can tell which is wrong."""
"""Added to every position tolerance: what the sigmas leave out (a robot body is not a perfect cylinder)."""


@dataclass(frozen=True, slots=True)
class Estimate:
    """Where one witness's sighting alone puts the target."""

    observer: str
    x_m: float
    y_m: float
    sigma_m: float


@dataclass(frozen=True, slots=True)
class Reference:
    """Where the target was held before this instant, and how well known that was."""

    x_m: float
    y_m: float
    sigma_m: float


def combine(estimates: Sequence[Estimate]) -> tuple[float, float, float]:
    """Inverse-variance mean of the estimates: (x, y, sigma)."""
    ws = [1.0 / max(e.sigma_m * e.sigma_m, 1e-9) for e in estimates]
    wsum = sum(ws)
    x = sum(w * e.x_m for w, e in zip(ws, estimates, strict=True)) / wsum
    y = sum(w * e.y_m for w, e in zip(ws, estimates, strict=True)) / wsum
    return x, y, 1.0 / math.sqrt(wsum)


def _off(e: Estimate, x: float, y: float, sigma: float, k: float) -> float:
    """How far ``e`` is from (x, y) in units of its tolerance (> 1: they disagree)."""
    return math.hypot(e.x_m - x, e.y_m - y) / (k * math.hypot(e.sigma_m, sigma) + SLACK_M)


def consistent(
    estimates: Sequence[Estimate], k: float, reference: Reference | None = None
) -> tuple[list[Estimate], list[str]]:
    """The estimates that agree with each other, and the observers of those refused."""
    kept = list(estimates)
    refused: list[str] = []
    while len(kept) >= PAIR_OF_WITNESSES:
        worst, worst_off = kept[0], 0.0
        for e in kept:
            x, y, s = combine([o for o in kept if o is not e])
            off = _off(e, x, y, s, k)
            if off > worst_off:
                worst, worst_off = e, off
        if worst_off <= 1.0:
            break
        if len(kept) == PAIR_OF_WITNESSES:
            if reference is None:
                break
            worst = max(kept, key=lambda e: _off(e, reference.x_m, reference.y_m, reference.sigma_m, k))
        kept.remove(worst)
        refused.append(worst.observer)
    return kept, refused


def blame(estimates: Sequence[Estimate], target: str, reference: Reference, k: float) -> list[str]:
    """Who put ``target`` where the solver refused it: the witnesses whose own estimate is off ``reference``
    (all of them if only their mean is), or the target itself when no witness placed it (its own sightings of
    known bodies did, by resection)."""
    if not estimates:
        return [target]
    off = [e.observer for e in estimates if _off(e, reference.x_m, reference.y_m, reference.sigma_m, k) > 1.0]
    return off or [e.observer for e in estimates]
