"""Ingest buffers (late, duplicate, out-of-order, clock steps, overflow) and alignment to the fusion instant."""

from __future__ import annotations

import math

import pytest

from common.schema import Blob, Features, Sighting
from resource_manager.ingest.align import AlignParams, align_sensor
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
    view = align_sensor(ing.buffers["p1"], "p1", (BASE_MS + 50) * MS, AlignParams())
    assert view is not None and view.mode == "interpolated"
    by = {b.local_id: b for b in view.blobs}
    assert abs(abs(by[7].bearing_rad) - math.pi) < 1e-9  # through ±pi, not through 0
    assert by[7].width_rad == pytest.approx(0.15)
    assert by[8].bearing_rad == pytest.approx(0.1)


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
    view = align_sensor(ing.buffers["p1"], "p1", (BASE_MS + t_ms) * MS, AlignParams())
    if mode is None:
        assert view is None
        return
    assert view is not None and view.mode == mode
    assert view.blobs[0].bearing_rad == pytest.approx(bearing)


def test_gap_too_long_is_not_interpolated() -> None:
    ing = Ingest()
    ing.add(frame(0, 0, [blob(1, 0.0)]))
    ing.add(frame(1, 1000, [blob(1, 1.0)]))
    view = align_sensor(ing.buffers["p1"], "p1", (BASE_MS + 950) * MS, AlignParams(max_gap_ns=500 * MS))
    assert view is not None and view.mode == "held" and view.blobs[0].bearing_rad == pytest.approx(1.0)


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
    view = align_sensor(ing.buffers["p1"], "p1", (BASE_MS + 50) * MS, AlignParams())
    assert view is not None
    (sg,) = view.sightings
    assert sg.left_rad == pytest.approx(0.2) and sg.right_rad == pytest.approx(0.0)


def test_trim_keeps_a_lower_bracket() -> None:
    ing = Ingest()
    for i in range(10):
        ing.add(frame(i, 100 * i))
    ing.trim((BASE_MS + 550) * MS)
    stamps = ing.buffers["p1"].stamps
    before = [t for t in stamps if t <= (BASE_MS + 550) * MS]
    assert before == [(BASE_MS + 400) * MS, (BASE_MS + 500) * MS]  # the bracket and one more for extrapolation


# -- world views of the aligned blobs (resource_manager/views/build.py) --------------------------------------------


def test_world_views_drop_known_bodies_keep_people() -> None:
    """A blob that is another camera's body is dropped; a person behind that body (taller top), a person
    elsewhere and a blob toward a camera without a body are kept; bearings rotate into the world; every
    view keeps its own histograms (none for a sensor that sends none)."""
    import numpy as np

    from common.schema import PanoramicModel, SensorInfo
    from resource_manager.ingest.align import AlignedBlob, AlignedView
    from resource_manager.poses.solver import PoseEstimate
    from resource_manager.views.build import build_views

    poses = {
        "a": PoseEstimate("a", 0.0, 0.0, 1.1, 0.3, "surveyed"),
        "b": PoseEstimate("b", 4.0, 0.0, 1.1, 0.0, "surveyed"),
        "c": PoseEstimate("c", 0.0, 4.0, 1.1, -1.0, "surveyed"),
    }
    radius = 0.2

    def seen(sid: str, lid: int, x: float, y: float, top_m: float, width_m: float, hist: list[float]) -> AlignedBlob:
        p = poses[sid]
        d = math.hypot(x - p.x_m, y - p.y_m)
        bearing = math.remainder(math.atan2(y - p.y_m, x - p.x_m) - p.yaw_rad, 2 * math.pi)
        top = math.atan2(top_m - p.z_m, d)
        return AlignedBlob(lid, bearing, 2 * math.asin(width_m / 2 / d), top, -0.2, hist, True, 100.0, 10.0)

    h1, h2, h3 = [0.5, 0.5, 0.0], [0.2, 0.3, 0.5], [1.0, 0.0, 0.0]
    blobs = {
        # a sees b's body (top at b's camera), a person behind b, a person elsewhere
        "a": [
            seen("a", 1, 4.0, 0.0, 1.0, 0.4, h1),
            seen("a", 2, 6.0, 0.0, 1.8, 0.45, h2),
            seen("a", 3, 2.0, 3.0, 1.7, 0.45, h3),
        ],
        # b sees c's body and camera a (no body: kept)
        "b": [seen("b", 7, 0.0, 4.0, 1.0, 0.4, h1), seen("b", 8, 0.0, 0.0, 1.0, 0.3, h2)],
        # c sends no histograms
        "c": [seen("c", 4, 2.0, 3.0, 1.7, 0.45, []), seen("c", 5, 4.0, 0.0, 1.0, 0.4, [])],
    }  # fmt: skip
    aligned = {sid: AlignedView(sid, 0, bl, [], "interpolated") for sid, bl in blobs.items()}
    model = PanoramicModel(width_px=1080, height_px=162, f_v_px=256.0, v0_px=93.0)

    def info(sid: str, body_m: float) -> SensorInfo:
        return SensorInfo(sensor_id=sid, seq=0, stamp_ns=1, kind="panoramic", model=model, body_radius_m=body_m)

    infos = {"a": info("a", 0.0), "b": info("b", radius), "c": info("c", radius)}
    views = build_views(aligned, poses, infos, lambda sid: 0.002)
    assert views.sensor_ids == ("a", "b", "c")
    assert views.local_id[views.span(0)].tolist() == [2, 3]  # b's body dropped, the person behind it kept
    assert views.local_id[views.span(1)].tolist() == [8]  # c's body dropped, camera a has no body
    assert views.local_id[views.span(2)].tolist() == [4]  # b's body dropped
    for row, sid in enumerate(views.sensor_ids):
        span = views.span(row)
        kept = [b for b in blobs[sid] if b.local_id in views.local_id[span].tolist()]
        world = [math.remainder(b.bearing_rad + poses[sid].yaw_rad, 2 * math.pi) for b in kept]
        bearing = views.bearing_rad[span]
        assert np.allclose(np.remainder(bearing - world + math.pi, 2 * math.pi) - math.pi, 0.0, atol=1e-12)
        assert views.width_rad[span].tolist() == [b.width_rad for b in kept]
        assert views.sigma_rad[row] == pytest.approx(0.002)
        if sid == "c":
            assert views.hist_bins[row] == 0
        else:
            assert views.hist_bins[row] == 3
            assert np.allclose(views.hist_sqrt[3][span] ** 2, [b.hist for b in kept])
    # Without bodies nothing is dropped.
    views = build_views(aligned, poses, {}, lambda sid: 0.002)
    assert views.counts.tolist() == [3, 2, 2]
