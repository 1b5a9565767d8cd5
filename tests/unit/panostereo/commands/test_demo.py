"""The demo's own rules: how long it scores, and what its summary warns about (a forged id) or only notes (a late
frame on a loaded machine)."""

from __future__ import annotations

import argparse

import pytest

from common.errors import ConfigError
from common.schema import ManagerStatus, Refusal
from common.site import DatasetSpec, SiteConfig, SiteSection
from panostereo.commands.demo import _refusals, _run_times, _split_refusals, _warnings

CLEAN = {"dropped": 0, "dropped_raw": 0, "unscored_s": 0.0}


def _status(*refused: Refusal) -> ManagerStatus:
    return ManagerStatus(manager_id="mgr1", seq=0, stamp_ns=0, tick_ms=1.0, tick_p99_ms=1.0, tick_rate_hz=10.0,
                         refused=list(refused))  # fmt: skip


def test_a_late_frame_is_a_note_and_a_forged_id_a_warning() -> None:
    refused = _refusals({"mgr1": _status(Refusal(sender_id="ptz1", skewed=1))})
    assert refused == {"ptz1": {"late": 1}}
    assert _split_refusals(refused) == ({}, {"ptz1": {"late": 1}})
    (level, text), *rest = _warnings(CLEAN, [], refused, {"ptz1", "pano1"})
    assert not rest and level == "NOTE" and "1 late frame(s) of ptz1" in text and "forged" not in text

    refused = _refusals({"mgr1": _status(Refusal(sender_id="pano1", wrong_id=3, ahead=2))})
    impostor, clock = _split_refusals(refused)
    assert impostor == {"pano1": {"wrong_id": 3}} and clock == {"pano1": {"ahead": 2}}
    lines = _warnings(CLEAN, [], refused, {"pano1"})
    assert [lvl for lvl, _ in lines] == ["WARNING", "WARNING"]
    assert "forged or misconfigured" in lines[0][1] and "clock synchronised" in lines[1][1]


def _site(dataset: bool = False) -> SiteConfig:
    return SiteConfig(site=SiteSection(name="s", duration_s=60.0), dataset=DatasetSpec(fps=7.0) if dataset else None)


@pytest.mark.parametrize(
    ("duration", "warmup", "dataset", "want"),
    [
        (None, None, False, (60.0, 5.0)),
        (5.0, None, False, (5.0, 2.5)),  # a short run is never refused for a warm-up the user did not set
        (30.0, 0.0, False, (30.0, 0.0)),
        (30.0, None, True, (30.0, 0.0)),
    ],
)
def test_run_times(duration: float | None, warmup: float | None, dataset: bool, want: tuple[float, float]) -> None:
    assert _run_times(_site(dataset), argparse.Namespace(duration=duration, warmup=warmup)) == want


@pytest.mark.parametrize(("duration", "warmup"), [(0.0, None), (-3.0, None), (float("inf"), None), (5.0, 6.0)])
def test_run_times_refuse_what_cannot_run(duration: float, warmup: float | None) -> None:
    with pytest.raises(ConfigError, match=r"--duration|--warmup"):
        _run_times(_site(), argparse.Namespace(duration=duration, warmup=warmup))
