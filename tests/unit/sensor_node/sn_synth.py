"""Synthetic panoramas drawn with cv2 for stage tests (no renderer needed)."""

from __future__ import annotations

import cv2
import numpy as np
import numpy.typing as npt

from common.cameras import CylindricalCamera

W, H = 1080, 162
WHITE = (255, 255, 255)


class ColumnGeometry:
    """Bearing = column, elevation = row (stages that need a geometry read heads off in pixels)."""

    wraps = True

    def bearing(self, u: float, v: float) -> float:
        return u

    def elevation(self, u: float, v: float) -> float:
        return v

    def width(self, u_left: float, u_right: float, v: float) -> float:
        return u_right - u_left


def backdrop(seed: int = 0, w: int = W, h: int = H) -> npt.NDArray[np.uint8]:
    """A smooth, textured BGR background."""
    rng = np.random.default_rng(seed)
    coarse = rng.integers(70, 170, (h // 8 + 1, w // 20 + 1, 3)).astype(np.uint8)
    return cv2.resize(coarse, (w, h), interpolation=cv2.INTER_LINEAR)


def draw_person(
    img: npt.NDArray[np.uint8],
    u: float,
    top: int = 40,
    head_w: int = 10,
    body_w: int = 22,
    body_offset: float = 0.0,
    shirt: tuple[int, int, int] = (30, 30, 200),
    head: tuple[int, int, int] = (200, 220, 240),
    neck_px: int = 0,
) -> None:
    """A person: elliptic head centred at column ``u`` and a body box (offset sideways by ``body_offset``),
    ``neck_px`` rows below the head's bottom (a neck half the head's width between them).

    Drawn with 1/16-px precision (cv2 shift=4); wraps around the panorama seam.
    """
    width = img.shape[1]
    for shift in (0, -width, width):
        cu = u + shift
        head_h = round(1.5 * head_w)
        b0 = cu + body_offset - body_w / 2
        if neck_px > 0:
            n0 = cu - head_w / 4
            cv2.rectangle(
                img,
                (round(n0 * 16), (top + head_h - 2) * 16),
                (round((n0 + head_w / 2) * 16), (top + head_h + neck_px) * 16),
                shirt,
                -1,
                shift=4,
            )
        cv2.rectangle(
            img,
            (round(b0 * 16), (top + head_h - 2 + neck_px) * 16),
            (round((b0 + body_w) * 16), (img.shape[0] + 5) * 16),
            shirt,
            -1,
            shift=4,
        )
        cv2.ellipse(
            img,
            (round(cu * 16), round((top + head_h / 2) * 16)),
            (round(head_w / 2 * 16), round(head_h / 2 * 16)),
            0,
            0,
            360,
            head,
            -1,
            lineType=cv2.LINE_AA,
            shift=4,
        )


def noisy(
    img: npt.NDArray[np.uint8], rng: np.random.Generator, sigma: float = 2.0, gain: float = 1.0
) -> npt.NDArray[np.uint8]:
    return np.clip(img.astype(np.float32) * gain + rng.normal(0, sigma, img.shape), 0, 255).astype(np.uint8)


def grey(img: npt.NDArray[np.uint8]) -> npt.NDArray[np.uint8]:
    return cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)


def mask_of(img: npt.NDArray[np.uint8]) -> npt.NDArray[np.uint8]:
    """255 wherever a drawing on black is (people drawn on a zero image as a foreground mask)."""
    return cv2.threshold(grey(img), 0, 255, cv2.THRESH_BINARY)[1]


def pano_camera() -> CylindricalCamera:
    """The W x H test panorama's cylindrical camera."""
    return CylindricalCamera(W, H, f_v_px=250.0, v0_px=93.0, height_m=1.1)
