"""Fixtures shared by the panostereo command and dataset tests."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.unit.panostereo.mot_synth import write_dataset


@pytest.fixture
def made(tmp_path: Path) -> Path:
    """A small calibrated MOT-layout dataset made in the test (3 people, 3 cameras, 30 frames at 5 fps)."""
    write_dataset(tmp_path / "data")
    return tmp_path / "data"
