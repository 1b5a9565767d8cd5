"""The recorded run shared by the recorder's, the reader's and the report's tests."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.unit.user_agent.recorded_run import record_run


@pytest.fixture
def recorded(tmp_path: Path) -> tuple[Path, Path]:
    return record_run(tmp_path)
