"""Reading a recording back: every raw sample with its key, the TrackSets, the SensorInfos, the invalid count."""

from __future__ import annotations

from pathlib import Path

from tests.unit.user_agent.recorded_run import K
from user_agent.recording import iter_raw, load_recording


def test_reader_returns_every_raw_sample_with_its_key(recorded: tuple[Path, Path]) -> None:
    mcap, _ = recorded
    raw = list(iter_raw(mcap))
    assert len(raw) == 2 + 1 + 160
    assert raw[0].key == K.sensor_info("pano1")
    rec = load_recording(mcap)
    assert rec.invalid == 1 and len(rec.tracksets) == 80 and set(rec.sensor_infos) == {"pano1", "pano2"}
