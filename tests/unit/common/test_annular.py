"""Annular PAL images (Steps 1-2): the designed lens, point and map round trips, ring centre, radial fit."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from common.annular import AnnularModel, center_from_lines, design_pal, fit_radial_polynomial
from common.errors import CalibrationError, ConfigError

PAL, PAL_CAM = design_pal()


def test_design_pal_rows_are_linear_perspective_over_the_paper_fov() -> None:
    assert (PAL.image_w, PAL.image_h, PAL.pano_w, PAL.pano_h) == (768, 576, 1080, 162)
    assert PAL_CAM.row_from_elevation(math.radians(20.0)) == pytest.approx(-0.5)
    assert PAL_CAM.row_from_elevation(math.radians(-15.0)) == pytest.approx(161.5)
    assert PAL_CAM.f_v_px == pytest.approx(256.36, abs=0.01)
    inner, outer = PAL.radius_range_px
    assert 0 < inner < outer
    # The ring stays inside the image.
    assert PAL.cx_px - outer >= 0 and PAL.cx_px + outer <= 767
    assert PAL.cy_px - outer >= 0 and PAL.cy_px + outer <= 575
    # The maximum perimeter is ~1800 px as in the paper (0.2 deg/px).
    assert 1700 < 2 * math.pi * outer < 1810


def test_design_pal_has_a_genuine_second_order_distortion() -> None:
    """Equal elevation steps land at unequal radius steps, and no straight line fits r(v)."""
    assert PAL.a2 != 0.0
    v = np.linspace(-0.5, 161.5, 50)
    r = PAL.a0 + PAL.a1 * v + PAL.a2 * v * v
    line = np.polyval(np.polyfit(v, r, 1), v)
    assert np.max(np.abs(r - line)) > 3.0  # px: visibly bent (paper's unequal bars, Fig. 1c)


@pytest.mark.parametrize("direction", [1, -1])
@pytest.mark.parametrize("psi0", [0.0, 2.0])
def test_annular_point_round_trip(direction: int, psi0: float) -> None:
    m = AnnularModel(768, 576, 380.0, 290.0, PAL.a0, PAL.a1, PAL.a2, 1080, 162, psi0_rad=psi0, direction=direction)
    rng = np.random.default_rng(3)
    u, v = rng.uniform(0, 1080, 500), rng.uniform(-0.5, 161.5, 500)
    x, y = m.annular_from_pano(u, v)
    u2, v2 = m.pano_from_annular(x, y)
    du = (u2 - u + 540) % 1080 - 540
    assert np.max(np.abs(du)) < 1e-6 and np.max(np.abs(v2 - v)) < 1e-6


def _bilinear(img: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    out = cv2.remap(img, x.astype(np.float32)[None], y.astype(np.float32)[None], cv2.INTER_LINEAR)
    return np.asarray(out[0], dtype=np.float64)


def test_warp_then_unwarp_maps_return_a_point_within_half_a_pixel() -> None:
    """Through the discrete maps: a panorama point goes to the annular image (unwarp map) and back (warp map)."""
    map_ux, map_uy = PAL.unwarp_maps()
    map_wx, map_wy = PAL.warp_maps()
    assert map_ux.shape == (162, 1080) and map_wx.shape == (576, 768)
    assert map_ux.dtype == np.float32 and map_wy.dtype == np.float32
    rng = np.random.default_rng(4)
    u, v = rng.uniform(1, 1078, 400), rng.uniform(1, 160, 400)
    x, y = _bilinear(map_ux, u, v), _bilinear(map_uy, u, v)
    u2, v2 = _bilinear(map_wx, x, y), _bilinear(map_wy, x, y)
    assert np.max(np.hypot(u2 - u, v2 - v)) < 0.5


def test_warp_maps_mark_outside_the_ring() -> None:
    map_x, map_y = PAL.warp_maps()
    assert map_x[int(PAL.cy_px), int(PAL.cx_px)] == -1 and map_y[0, 0] == -1
    inner, outer = PAL.radius_range_px
    r_mid = (inner + outer) / 2
    assert map_x[round(PAL.cy_px), round(PAL.cx_px + r_mid)] >= 0


def test_image_warp_then_unwarp_keeps_a_vertical_line_in_its_column() -> None:
    pano = np.full((162, 1080), 20, np.uint8)
    pano[:, 300] = 250
    pano[:, 1079] = 250  # at the seam too
    wx, wy = PAL.warp_maps()
    padded = np.concatenate([pano, pano[:, :1]], axis=1)
    annular = cv2.remap(padded, wx, wy, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    ux, uy = PAL.unwarp_maps()
    back = cv2.remap(annular, ux, uy, cv2.INTER_LINEAR).astype(np.float64)
    rows = back[5:157]
    assert np.all(np.abs(np.argmax(rows[:, 200:400], axis=1) + 200 - 300) <= 1)
    seam = np.concatenate([rows[:, -20:], rows[:, :20]], axis=1)
    assert np.all(np.abs(np.argmax(seam, axis=1) - 19) <= 1)
    # Sub-pixel: the intensity-weighted column of the line stays within 0.5 px.
    win = rows[:, 295:306] - 20
    centroid = (win * np.arange(295, 306)).sum(axis=1) / win.sum(axis=1)
    assert np.max(np.abs(centroid - 300)) < 0.5


@pytest.mark.parametrize("a2", [0.02, -0.02])
def test_annular_rejects_non_monotonic_radius(a2: float) -> None:
    with pytest.raises(ConfigError, match="monotonic"):
        AnnularModel(768, 576, 384, 288, 200.0, -1.0 if a2 > 0 else 1.0, a2, 1080, 162)


def test_center_from_two_exact_lines() -> None:
    cx, cy = center_from_lines([np.array([[10.0, 10.0], [20.0, 20.0]]), np.array([[0.0, 30.0], [30.0, 0.0]])])
    assert (cx, cy) == (pytest.approx(15.0), pytest.approx(15.0))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_center_from_noisy_vertical_lines(seed: int) -> None:
    """Five imaged vertical lines (spread round the ring, 0.5 px noise) locate the centre within 0.75 px.

    (Median error over many seeds ~0.27 px, 99th percentile ~0.7 px.)
    """
    rng = np.random.default_rng(seed)
    lines = []
    for psi in np.arange(5) * 2 * np.pi / 5 + rng.uniform(0, 1.0, 5):
        x, y = PAL.annular_from_pano(np.full(30, psi * 1080 / (2 * np.pi)), np.linspace(0, 161, 30))
        lines.append(np.column_stack([x, y]) + rng.normal(0, 0.5, (30, 2)))
    cx, cy = center_from_lines(lines)
    assert math.hypot(cx - PAL.cx_px, cy - PAL.cy_px) < 0.5


@pytest.mark.parametrize(
    "lines",
    [
        [np.array([[0.0, 0.0], [1.0, 1.0]])],
        [np.array([[0.0, 0.0], [1.0, 0.0]]), np.array([[0.0, 5.0], [1.0, 5.0]])],
        [np.array([[0.0, 0.0], [0.0, 0.0]]), np.array([[0.0, 5.0], [1.0, 5.0]])],
    ],
)
def test_center_from_lines_rejects_degenerate(lines: list[np.ndarray]) -> None:
    with pytest.raises(CalibrationError):
        center_from_lines(lines)


def test_fit_radial_polynomial_recovers_the_lens() -> None:
    """Step 2: 3 exact pairs give the polynomial; 12 noisy pairs (0.3 px) give r(v) within 0.5 px everywhere.

    (Median worst-row error over many seeds ~0.24 px.)
    """
    v = np.array([0.0, 80.0, 161.0])
    r = PAL.a0 + PAL.a1 * v + PAL.a2 * v * v
    assert fit_radial_polynomial(v, r) == pytest.approx((PAL.a0, PAL.a1, PAL.a2), rel=1e-9)
    rng = np.random.default_rng(0)
    v = np.linspace(0, 161, 12)
    r = PAL.a0 + PAL.a1 * v + PAL.a2 * v * v + rng.normal(0, 0.3, 12)
    a0, a1, a2 = fit_radial_polynomial(v, r)
    vv = np.linspace(0, 161, 100)
    err = (a0 + a1 * vv + a2 * vv**2) - (PAL.a0 + PAL.a1 * vv + PAL.a2 * vv**2)
    assert np.max(np.abs(err)) < 0.5


@pytest.mark.parametrize(
    ("v", "r"), [([1.0, 2.0], [3.0, 4.0]), ([1.0, 1.0, 1.0], [2.0, 2.0, 2.0]), ([1, 2, 3], [1, 2])]
)
def test_fit_radial_polynomial_rejects_bad_input(v: list[float], r: list[float]) -> None:
    with pytest.raises(CalibrationError):
        fit_radial_polynomial(v, r)


@pytest.mark.parametrize("seed", [0, 1])
def test_steps_1_and_2_recover_the_lens_from_noisy_image_points(seed: int) -> None:
    """Centre from 8 imaged vertical lines, then the radial polynomial from marks at known elevations.

    Marks every 2.5 deg of elevation on 8 vertical poles, imaged with 0.3 px noise. The
    rebuilt model maps every panorama pixel within 0.6 px of the true lens (worst pixel:
    median 0.26 px, max 0.50 px over 100 seeds).
    """
    rng = np.random.default_rng(seed)
    elevations = np.radians(np.arange(-15.0, 20.1, 2.5))
    rows_true = PAL_CAM.row_from_elevation(elevations)
    cols = np.arange(8) * 135.0 + rng.uniform(0, 60)
    marks = [
        np.column_stack(PAL.annular_from_pano(np.full(rows_true.size, u), rows_true))
        + rng.normal(0, 0.3, (rows_true.size, 2))
        for u in cols
    ]
    cx, cy = center_from_lines(marks)
    radii = np.concatenate([np.hypot(m[:, 0] - cx, m[:, 1] - cy) for m in marks])
    a0, a1, a2 = fit_radial_polynomial(np.tile(rows_true, len(marks)), radii)
    rebuilt = AnnularModel(768, 576, cx, cy, a0, a1, a2, 1080, 162)
    vv, uu = np.mgrid[0:162:7, 0:1080:13].astype(float)
    x0, y0 = PAL.annular_from_pano(uu, vv)
    x1, y1 = rebuilt.annular_from_pano(uu, vv)
    assert np.max(np.hypot(x1 - x0, y1 - y0)) < 0.6
