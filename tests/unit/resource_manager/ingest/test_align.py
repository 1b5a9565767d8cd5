"""Ingest buffers (late, duplicate, out-of-order, clock steps, overflow) and alignment to the fusion instant."""

from __future__ import annotations

import math

import pytest

from common.schema import Blob, Features, Sighting
from resource_manager.ingest.align import ALIGNED_COLUMNS, Aligned, AlignParams, align
from resource_manager.ingest.buffers import Ingest

MS = 1_000_000
BASE_MS = 10_000
"""Stamps are BASE_MS + t (all after the initial "last fusion instant" of 0)."""


def blob(lid: int, bearing: float, width: float = 0.1, top: float = 0.2) -> Blob:
    return Blob(
        local_id=lid,
        bearing_rad=bearing,
        width_rad=width,
        top_elev_rad=top,
        bottom_elev_rad=-0.3,
        bbox_u_px=0,
        bbox_v_px=0,
        bbox_w_px=1,
        bbox_h_px=1,
    )


def align_one(ing: Ingest, t_ms: int, params: AlignParams | None = None) -> Aligned:
    """Sensor p1's blobs aligned at ``BASE_MS + t_ms``."""
    return align([("p1", ing.buffers["p1"], params or AlignParams())], (BASE_MS + t_ms) * MS)


def frame(seq: int, t_ms: int, blobs: list[Blob] | None = None, sid: str = "p1", **kw: object) -> Features:
    return Features(
        sensor_id=sid,
        seq=seq,
        stamp_ns=(BASE_MS + t_ms) * MS,
        frame_index=seq,
        blobs=blobs or [],
        **kw,  # type: ignore[arg-type]
    )


@pytest.mark.parametrize(
    ("arrivals", "fused_ms", "expect_kinds", "expect_stamps_ms"),
    [
        ([(0, 0), (1, 100), (2, 200)], 0, ["accepted"] * 3, [0, 100, 200]),
        ([(0, 0), (2, 200), (1, 100)], 0, ["accepted", "accepted", "out_of_order"], [0, 100, 200]),
        ([(0, 0), (1, 100), (1, 100)], 0, ["accepted", "accepted", "duplicate"], [0, 100]),
        ([(0, 100), (1, 200), (2, 50)], 80, ["accepted", "accepted", "out_of_order"], [50, 100, 200]),
        ([(5, 1000), (6, 1100), (7, 40)], 0, ["accepted", "accepted", "clock_step"], [40]),
        ([(5, 1000), (6, 1100), (2, 40)], 0, ["accepted", "accepted", "out_of_order"], [40, 1000, 1100]),
    ],
)
def test_ingest_kinds(
    arrivals: list[tuple[int, int]], fused_ms: int, expect_kinds: list[str], expect_stamps_ms: list[int]
) -> None:
    ing = Ingest(capacity=8, clock_step_ns=500 * MS)
    ing.last_fusion_ns = (BASE_MS + fused_ms) * MS if fused_ms else 0
    kinds = [ing.add(frame(seq, t)) for seq, t in arrivals]
    assert kinds == expect_kinds
    assert ing.buffers["p1"].stamps == [(BASE_MS + t) * MS for t in expect_stamps_ms]
    if fused_ms:
        assert ing.counters.late == 1  # behind the last fusion instant: late as well as out of order


def test_late_counted_and_overflow_bounded() -> None:
    ing = Ingest(capacity=4)
    for i in range(10):
        ing.add(frame(i, 100 * i))
    assert len(ing.buffers["p1"].frames) == 4 and ing.counters.dropped == 6
    ing.last_fusion_ns = (BASE_MS + 950) * MS
    ing.add(frame(20, 920))
    assert ing.counters.late == 1


def test_interpolation_shortest_arc_and_by_local_id() -> None:
    ing = Ingest()
    ing.add(frame(0, 0, [blob(7, math.pi - 0.1, width=0.10), blob(8, 0.0)]))
    ing.add(frame(1, 100, [blob(8, 0.2), blob(7, -math.pi + 0.1, width=0.20)]))
    view = align_one(ing, 50)
    assert view.sensor_ids == ("p1",) and view.modes == ("interpolated",)
    by = {lid: k for k, lid in enumerate(view.local_id.tolist())}
    assert abs(abs(view.bearing_rad[by[7]]) - math.pi) < 1e-9  # through ±pi, not through 0
    assert view.width_rad[by[7]] == pytest.approx(0.15)
    assert view.bearing_rad[by[8]] == pytest.approx(0.1)
    assert view.hist == [[], []] and view.values[:, 3] == pytest.approx([-0.3, -0.3])  # feet visible in both


@pytest.mark.parametrize(
    ("t_ms", "mode", "bearing"),
    [
        (150, "extrapolated", 0.3),  # 50 ms past the newest frame: constant-rate extrapolation
        (260, None, None),  # beyond max extrapolation (100 ms): sits the tick out
        (-50, "held", 0.0),  # before the first frame, within the limit: held
        (5000, None, None),  # stale
    ],
)
def test_extrapolation_limits(t_ms: int, mode: str | None, bearing: float | None) -> None:
    ing = Ingest()
    ing.add(frame(0, 0, [blob(1, 0.0)]))
    ing.add(frame(1, 100, [blob(1, 0.2)]))
    view = align_one(ing, t_ms)
    if mode is None:
        assert view.sensor_ids == () and view.values.shape == (0, ALIGNED_COLUMNS)  # it sits the tick out
        return
    assert view.modes == (mode,)
    assert view.bearing_rad[0] == pytest.approx(bearing)


def test_gap_too_long_is_not_interpolated() -> None:
    ing = Ingest()
    ing.add(frame(0, 0, [blob(1, 0.0)]))
    ing.add(frame(1, 1000, [blob(1, 1.0)]))
    view = align_one(ing, 950, AlignParams(max_gap_ns=500 * MS))
    assert view.modes == ("held",) and view.bearing_rad[0] == pytest.approx(1.0)


def test_sightings_interpolated_by_target() -> None:
    def s(left: float, right: float) -> Sighting:
        return Sighting(
            target_id="r1",
            left_rad=left,
            right_rad=right,
            alpha_rad=abs(left - right),
            bearing_rad=(left + right) / 2,
            distance_m=2.0,
            body_radius_m=0.18,
        )

    ing = Ingest()
    ing.add(frame(0, 0, sightings=[s(0.1, -0.1)]))
    ing.add(frame(1, 100, sightings=[s(0.3, 0.1)]))
    view = align_one(ing, 50)
    (sg,) = view.sightings["p1"]
    assert sg.left_rad == pytest.approx(0.2) and sg.right_rad == pytest.approx(0.0)


def test_trim_keeps_a_lower_bracket() -> None:
    ing = Ingest()
    for i in range(10):
        ing.add(frame(i, 100 * i))
    ing.trim((BASE_MS + 550) * MS)
    stamps = ing.buffers["p1"].stamps
    before = [t for t in stamps if t <= (BASE_MS + 550) * MS]
    assert before == [(BASE_MS + 400) * MS, (BASE_MS + 500) * MS]  # the bracket and one more for extrapolation
