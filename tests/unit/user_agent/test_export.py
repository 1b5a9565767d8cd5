"""`agent export`: any recording's tracks as CSV or MOTChallenge rows, with no ground truth and no epoch."""

from __future__ import annotations

import csv
from pathlib import Path

import msgspec
import pytest

from common.codec import encode
from common.keys import Keys
from common.schema import TrackSet
from panostereo.cli import main
from tests.unit.user_agent.recorded_run import EPOCH, track
from user_agent.export import CSV_HEADER, export_rows, mot_ids
from user_agent.record import McapSink

K = Keys("pano")


def _sets() -> list[TrackSet]:
    """Ten ticks at 10 Hz of mgr1 (one confirmed track, one tentative) and, from tick 5, mgr2's track."""
    out = []
    for i in range(10):
        stamp = EPOCH + i * 100_000_000
        tent = msgspec.structs.replace(track("mgr1-2", 9.0, 9.0, stamp), state="tentative")
        out.append(
            TrackSet(manager_id="mgr1", seq=i, stamp_ns=stamp, tracks=[track("mgr1-1", 1.0 + i, 2.0, stamp), tent])
        )
        if i >= 5:
            other = msgspec.structs.replace(track("mgr2-1", 5.0, 5.0, stamp + 1), manager_id="mgr2")
            out.append(TrackSet(manager_id="mgr2", seq=i, stamp_ns=stamp + 1, tracks=[other]))
    return out


def test_rows_are_the_published_tracks_by_instant() -> None:
    rows = export_rows(_sets())
    assert len(rows) == 15 and {tr.track_id for _, _, tr in rows} == {"mgr1-1", "mgr2-1"}  # tentative left out
    assert rows[0][:2] == (1, 0.0) and rows[-1][0] == 15  # every instant of every manager is a frame
    assert export_rows(_sets(), epoch_ns=EPOCH - 2_000_000_000)[0][1] == pytest.approx(2.0)


@pytest.mark.parametrize(
    ("ids", "want"),
    [(["mgr1-7", "mgr1-2"], {"mgr1-7": 7, "mgr1-2": 2}), (["a-1", "b-1"], {"a-1": 1, "b-1": 2}), (["x"], {"x": 1})],
)
def test_mot_ids_are_the_tracks_numbers_when_those_are_unique(ids: list[str], want: dict[str, int]) -> None:
    assert mot_ids(ids) == want


def test_the_command_exports_a_recording_without_epoch_or_ground_truth(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    sink = McapSink(tmp_path / "up.mcap", {"prefix": "pano"}, foxglove=False)  # as `agent record` on an `up` site
    for ts in _sets():
        sink.write(K.tracks(), encode(ts), ts.stamp_ns)
    sink.close()
    assert main(["agent", "export", str(tmp_path / "up.mcap"), "--out", str(tmp_path / "t.csv")]) == 0
    assert "wrote 15 rows (2 tracks over 15 frames)" in capsys.readouterr().out
    rows = list(csv.reader((tmp_path / "t.csv").read_text().splitlines()))
    assert tuple(rows[0]) == CSV_HEADER and rows[1][:5] == ["1", "0.000", "mgr1-1", "1.0000", "2.0000"]
    assert (
        main(["agent", "export", str(tmp_path / "up.mcap"), "--out", str(tmp_path / "t.txt"), "--format", "mot"]) == 0
    )
    mot = [r.split(",") for r in (tmp_path / "t.txt").read_text().splitlines()]
    assert mot[0] == ["1", "1", "-1", "-1", "-1", "-1", "1", "1.0000", "2.0000", "0"]
    assert sorted({r[1] for r in mot}) == ["1", "2"]  # two managers' "-1" tracks: numbered in order instead
    assert main(["agent", "export", str(tmp_path / "none.mcap"), "--out", str(tmp_path / "x.csv")]) == 1
    assert "no such recording" in capsys.readouterr().err
