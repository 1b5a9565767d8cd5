"""Stage 1: annular (PAL) image -> cylindrical panorama by a precomputed remap.

The maps come from the calibrated :class:`common.cameras.AnnularModel` (paper
Steps 1-2: ring centre and 2nd-order radial polynomial); they are computed once
and converted to OpenCV's fixed-point form (1/32 px interpolation steps), which
remaps about twice as fast as float maps with no visible loss.
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy.typing as npt

from common.cameras import AnnularModel
from common.errors import SourceError

__all__ = ["Unwarper"]

Image = npt.NDArray[Any]
"""An 8-bit image (cv2 results are typed loosely)."""


class Unwarper:
    """Turns annular frames of one lens into panoramas.

    Args:
        model: the calibrated annular model (image size, centre, radial polynomial, panorama size).
        fixed_point: use fixed-point maps (faster); False keeps the float maps (exact bilinear).
    """

    def __init__(self, model: AnnularModel, fixed_point: bool = True) -> None:
        self.model = model
        map_x, map_y = model.unwarp_maps()
        if fixed_point:
            self._m1, self._m2 = cv2.convertMaps(map_x, map_y, cv2.CV_16SC2)
        else:
            self._m1, self._m2 = map_x, map_y

    @property
    def pano_size(self) -> tuple[int, int]:
        """(width, height) of the panorama."""
        return self.model.pano_w, self.model.pano_h

    def apply(self, annular: Image, out: Image | None = None) -> Image:
        """Unwarp one annular frame (grey or BGR) into a panorama of the same channel count.

        Raises:
            SourceError: if the frame size differs from the calibrated image size.
        """
        h, w = annular.shape[:2]
        if (w, h) != (self.model.image_w, self.model.image_h):
            raise SourceError(
                f"frame is {w}x{h} px but the camera calibration is for {self.model.image_w}x{self.model.image_h}"
            )
        return cv2.remap(annular, self._m1, self._m2, cv2.INTER_LINEAR, dst=out, borderMode=cv2.BORDER_REPLICATE)
