"""Who was followed by which track, and when: the data behind the plot's timeline and its colours.

Pure (no drawing, no I/O). With ground truth, each ground-truth frame is scored by the same CLEAR-MOT rules as
``agent evaluate`` (:func:`~user_agent.evaluate.evaluate_positions`); each person gets one row, holding the
spans where a track followed them (a MATCH or SWITCH event of that frame), the spans where they were there
but missed, and every id switch (the event CLEAR-MOT counts: the track following them is not the one that
did last). Each track is then "the track of" the person it followed in most frames, so a plot can colour it
like that person. Without ground truth, each track gets a row of its own: where it was published.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

from common.arrays import FloatArray
from common.schema import TrackSet
from user_agent.evaluate import DEFAULT_STATES, evaluate_positions, hypotheses_from_tracksets
from user_agent.groundtruth import GroundTruth

__all__ = ["Span", "Switch", "Timeline", "timeline_of_tracks", "timeline_with_truth"]


@dataclass(frozen=True, slots=True)
class Span:
    """A stretch of one row: a track following (``track_id``), or the row's person missed (``track_id`` "")."""

    row: str
    track_id: str
    t0_s: float
    t1_s: float
    """World time (s after the run's epoch), the span covering whole frames."""


@dataclass(frozen=True, slots=True)
class Switch:
    """An id switch: from this instant another track follows the row's person."""

    row: str
    t_s: float
    from_track: str
    to_track: str


@dataclass(frozen=True, slots=True)
class Timeline:
    """Rows (people, or tracks without ground truth) in order of first appearance, and what happened in each."""

    rows: list[str]
    spans: list[Span]
    switches: list[Switch] = field(default_factory=list)
    track_person: dict[str, str] = field(default_factory=dict)
    """Track -> the person it followed in most frames (absent: it followed nobody; a false track)."""
    main_track: dict[str, str] = field(default_factory=dict)
    """Person -> the track that followed them in most frames."""
    with_truth: bool = False

    @property
    def tracks(self) -> list[str]:
        """Every track that appears, in order of first appearance."""
        seen: dict[str, float] = {}
        for s in sorted(self.spans, key=lambda s: s.t0_s):
            if s.track_id:
                seen.setdefault(s.track_id, s.t0_s)
        return list(seen)


def _runs(row: str, values: Sequence[tuple[float, str]], half_s: float) -> list[Span]:
    """Merge consecutive frames (time, value) with one value into spans; a gap of a frame or more splits them."""
    out: list[Span] = []
    for t, value in values:
        last = out[-1] if out else None
        if last is not None and last.track_id == value and t - half_s <= last.t1_s + 1e-9:
            out[-1] = Span(row, value, last.t0_s, t + half_s)
        else:
            out.append(Span(row, value, t - half_s, t + half_s))
    return out


def timeline_with_truth(
    tracksets: Sequence[TrackSet],
    gt: GroundTruth,
    *,
    epoch_ns: int,
    fps: float,
    threshold_m: float = 0.5,
    area: FloatArray | None = None,
    states: Sequence[str] = DEFAULT_STATES,
) -> Timeline:
    """One row per ground-truth person over the frames the TrackSets cover, scored as ``agent evaluate`` does.

    Args:
        epoch_ns, fps: ground-truth frame ``k`` is world time ``(k - 1) / fps`` after ``epoch_ns``.
        threshold_m: a track farther than this from a person cannot be following them.
        area: where the ground truth annotates people (tracks outside are not scored; see ``evaluate``).
    """
    hyps, frames = hypotheses_from_tracksets(tracksets, epoch_ns, fps, gt.frame_numbers, states=states)
    per_person: dict[str, list[tuple[float, str]]] = {}
    switches: list[Switch] = []
    follows: Counter[tuple[str, str]] = Counter()

    def on_events(k: int, events: list[tuple[str, str, str, float]]) -> None:
        t = (k - 1) / fps
        for kind, person, track, _ in events:
            if kind in ("MATCH", "SWITCH"):
                per_person.setdefault(person, []).append((t, track))
                follows[(person, track)] += 1
            elif kind == "MISS":
                per_person.setdefault(person, []).append((t, ""))
            if kind == "SWITCH":
                before = next((h for _, h in reversed(per_person[person][:-1]) if h), "")
                switches.append(Switch(person, t, before, track))

    evaluate_positions(gt, hyps, threshold_m, frames=frames, on_events=on_events, area=area)
    half = 0.5 / fps
    rows = sorted(per_person, key=lambda p: (per_person[p][0][0], p))
    spans = [s for p in rows for s in _runs(p, per_person[p], half)]
    track_person: dict[str, str] = {}
    main: dict[str, str] = {}
    for person, track in sorted(follows, key=lambda pair: (-follows[pair], pair)):  # most frames first
        track_person.setdefault(track, person)
        main.setdefault(person, track)
    return Timeline(rows, spans, switches, track_person, main, with_truth=True)


def timeline_of_tracks(
    tracksets: Iterable[TrackSet], *, epoch_ns: int, period_s: float, states: Sequence[str] = DEFAULT_STATES
) -> Timeline:
    """One row per track: the instants it was published in one of ``states`` (no ground truth needed).

    Args:
        epoch_ns: time 0 of the plot (the run's epoch, or its first TrackSet).
        period_s: a track unseen for longer than this has a gap there.
    """
    seen: dict[str, list[float]] = {}
    for ts in sorted(tracksets, key=lambda t: t.stamp_ns):
        t = (ts.stamp_ns - epoch_ns) / 1e9
        for tr in ts.tracks:
            if tr.state in states:
                seen.setdefault(tr.track_id, []).append(t)
    spans: list[Span] = []
    half = period_s / 2
    for tid, times in seen.items():
        spans += _runs(tid, [(t, tid) for t in times], half)
    rows = sorted(seen, key=lambda tid: (seen[tid][0], tid))
    return Timeline(rows, spans, track_person={}, main_track={tid: tid for tid in rows})
