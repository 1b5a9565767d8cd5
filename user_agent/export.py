"""A recording's tracks as a table other tools read: no ground truth, no epoch needed.

Pure (no zenoh, no mcap): TrackSets in, rows out. Each fusion instant of the recording (a TrackSet's
``stamp_ns``; with several managers, each of theirs) is one frame, numbered from 1 in time order; its time is
in seconds after the run's epoch when the recording stores one, else after its first TrackSet.

* ``csv``: ``frame,time_s,id,x_m,y_m,height_m,vx_mps,vy_mps,state,manager_id``, one row per published track
  (confirmed or coasting) per frame.
* ``mot``: MOTChallenge 3D-style rows ``frame,id,-1,-1,-1,-1,1,x,y,z`` (no image box; world position in metres,
  z 0 on the floor), with integer ids: a track's number (``mgr1-7`` -> 7) when one manager made them all, else
  numbers in order of first appearance.
"""

from __future__ import annotations

import csv
from collections.abc import Sequence
from pathlib import Path
from typing import Literal

from common.errors import ConfigError
from common.schema import Track, TrackSet
from user_agent.evaluate import DEFAULT_STATES

__all__ = ["CSV_HEADER", "EXPORT_FORMATS", "export_rows", "mot_ids", "write_export"]

ExportFormat = Literal["csv", "mot"]
EXPORT_FORMATS: tuple[ExportFormat, ...] = ("csv", "mot")
CSV_HEADER = ("frame", "time_s", "id", "x_m", "y_m", "height_m", "vx_mps", "vy_mps", "state", "manager_id")


def export_rows(
    tracksets: Sequence[TrackSet], *, epoch_ns: int | None = None, states: Sequence[str] = DEFAULT_STATES
) -> list[tuple[int, float, Track]]:
    """(frame, time_s, track) for every published track of every TrackSet, frames 1-based in time order."""
    ordered = sorted(tracksets, key=lambda ts: (ts.stamp_ns, ts.manager_id))
    if not ordered:
        return []
    zero = epoch_ns if epoch_ns is not None else ordered[0].stamp_ns
    frames = {stamp: k for k, stamp in enumerate(sorted({ts.stamp_ns for ts in ordered}), start=1)}
    return [
        (frames[ts.stamp_ns], (ts.stamp_ns - zero) / 1e9, tr)
        for ts in ordered
        for tr in sorted(ts.tracks, key=lambda t: t.track_id)
        if tr.state in states
    ]


def mot_ids(track_ids: Sequence[str]) -> dict[str, int]:
    """Integer ids for MOTChallenge files: each track's own number when they are distinct, else 1, 2, ... in order."""
    numbers: dict[str, int] = {}
    for tid in track_ids:
        head, _, tail = tid.rpartition("-")
        if not (head and tail.isdigit()):
            break
        numbers[tid] = int(tail)
    if len(numbers) == len(track_ids) and len(set(numbers.values())) == len(numbers):
        return numbers
    return {tid: k for k, tid in enumerate(track_ids, start=1)}


def write_export(path: str | Path, rows: Sequence[tuple[int, float, Track]], fmt: ExportFormat = "csv") -> int:
    """Write the rows in ``fmt``; returns how many were written.

    Raises:
        ConfigError: an unknown format or a file that cannot be written.
    """
    if fmt not in EXPORT_FORMATS:
        raise ConfigError(f"export format must be one of {', '.join(EXPORT_FORMATS)}, got {fmt!r}")
    p = Path(path)
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
        with p.open("w", newline="", encoding="utf-8") as fh:
            out = csv.writer(fh)
            if fmt == "csv":
                out.writerow(CSV_HEADER)
                for k, t, tr in rows:
                    out.writerow([k, f"{t:.3f}", tr.track_id, f"{tr.x_m:.4f}", f"{tr.y_m:.4f}", f"{tr.height_m:.3f}",
                                  f"{tr.vx_mps:.3f}", f"{tr.vy_mps:.3f}", tr.state, tr.manager_id])  # fmt: skip
            else:
                ids = mot_ids(list(dict.fromkeys(tr.track_id for _, _, tr in rows)))
                for k, _, tr in rows:
                    out.writerow([k, ids[tr.track_id], -1, -1, -1, -1, 1, f"{tr.x_m:.4f}", f"{tr.y_m:.4f}", 0])
    except OSError as err:
        raise ConfigError(f"{p}: cannot write the export: {err.strerror}") from err
    return len(rows)
