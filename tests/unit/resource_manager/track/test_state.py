"""A track's record: its state from whether it was confirmed and detected."""

from __future__ import annotations

import pytest

from resource_manager.track.state import TrackRecord


@pytest.mark.parametrize(
    ("confirmed", "detected", "state"),
    [(False, True, "tentative"), (False, False, "tentative"), (True, True, "confirmed"), (True, False, "coasting")],
)
def test_state_follows_confirmation_and_detection(confirmed: bool, detected: bool, state: str) -> None:
    assert TrackRecord(serial=1, born_ns=0, confirmed=confirmed, detected=detected).state() == state
