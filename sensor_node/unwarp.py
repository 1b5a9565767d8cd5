"""Stage 1: annular (PAL) image -> cylindrical panorama by precomputed remaps.

The maps come from the calibrated :class:`common.cameras.AnnularModel` (paper
Steps 1-2: ring centre and 2nd-order radial polynomial); they are computed once
and converted to OpenCV's fixed-point form (1/32 px interpolation steps).

What the pipeline needs from a frame is cheaper than a full colour panorama:

* geometry (background model, blobs, heads) needs full resolution but one
  channel: the annular frame is converted to grey *before* the remap, a third
  of the remap work;
* colour (histograms, shadows, the robots' band colours) needs little
  resolution: a half-resolution colour panorama sampled with nearest-neighbour
  maps, made whole only when asked for (the warm-up's colour samples), else
  read in parts (rows for the band search and the colour background's
  update; a blob's or a shadow candidate's pixels, gathered by index from the
  annular frame);
* the sub-pixel boundaries of a sighted robot need full-resolution colour on a
  small box only: :meth:`PanoFrame.colour` remaps just that box.
"""

from __future__ import annotations

import cv2
import numpy as np
import numpy.typing as npt

from common.arrays import Image
from common.cameras import AnnularModel
from common.errors import SourceError

__all__ = ["PanoFrame", "Unwarper"]


def _wrap_cols(a: Image, u0: int, v0: int, w: int, h: int) -> Image:
    width = a.shape[1]
    u0 %= width
    rows = slice(max(0, v0), v0 + h)
    if u0 + w <= width:
        return a[rows, u0 : u0 + w]
    return np.concatenate([a[rows, u0:], a[rows, : u0 + w - width]], axis=1)


class PanoFrame:
    """One frame as the pipeline uses it: full-resolution grey, colour on demand.

    Args:
        grey: (H, W) full-resolution grey panorama (or perspective image).
        source: the frame as captured (annular, or the perspective image itself).
        scale: reduction of the colour views.
        maps: full-resolution fixed-point remap maps (None: ``source`` already is the processed image).
        small_maps: nearest-neighbour maps of the reduced colour panorama (with ``maps``).
        small_index: each reduced pixel's flat index into ``source``'s pixels (what ``small_maps`` reads;
            None: some read outside the frame, or no maps).
    """

    __slots__ = ("_small", "grey", "maps", "scale", "small_index", "small_maps", "source")

    def __init__(
        self,
        grey: Image,
        source: Image,
        scale: int = 2,
        maps: tuple[Image, Image] | None = None,
        small_maps: Image | None = None,
        *,
        small_index: Image | None = None,
    ) -> None:
        self.grey = grey
        self.source = source
        self.scale = scale
        self.maps = maps
        self.small_maps = small_maps
        self.small_index = small_index
        self._small: Image | None = None

    @classmethod
    def from_image(cls, bgr: Image, scale: int = 2) -> PanoFrame:
        """A frame that needs no unwarping (a perspective camera)."""
        return cls(cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY), bgr, scale)

    @property
    def small(self) -> Image:
        """(H / scale, W / scale, 3) reduced colour image (computed on first use)."""
        if self._small is None:
            if self.small_maps is None:
                self._small = np.ascontiguousarray(self.source[:: self.scale, :: self.scale])
            else:
                self._small = cv2.remap(self.source, self.small_maps, None, cv2.INTER_NEAREST)  # type: ignore[call-overload, unused-ignore]
        return self._small

    @property
    def small_shape(self) -> tuple[int, int]:
        """(rows, columns) of :attr:`small`, without computing it."""
        if self._small is not None:
            return self._small.shape[0], self._small.shape[1]
        if self.small_maps is not None:
            return self.small_maps.shape[0], self.small_maps.shape[1]
        return -(-self.source.shape[0] // self.scale), -(-self.source.shape[1] // self.scale)

    def small_at(self, at: npt.NDArray[np.integer]) -> Image:
        """(N, 3) pixels of :attr:`small` at the flat indices ``at`` (row * columns + column), without
        computing all of it."""
        if self._small is not None:
            return np.take(self._small.reshape(-1, 3), at, axis=0)
        if self.small_index is not None:
            return np.take(self.source.reshape(-1, 3), np.take(self.small_index, at), axis=0)
        if self.small_maps is None:
            rows, cols = np.divmod(at, self.small_shape[1])
            return np.take(
                self.source.reshape(-1, 3), (rows * self.scale) * self.source.shape[1] + cols * self.scale, axis=0
            )
        return np.take(self.small.reshape(-1, 3), at, axis=0)

    def small_box(self, c0: int, r0: int, w: int, h: int) -> Image:
        """The box (c0, r0, w, h) of :attr:`small` without computing all of it; columns wrap."""
        if self._small is not None or self.small_maps is None:
            return np.ascontiguousarray(_wrap_cols(self.small, c0, r0, w, h))
        m = np.ascontiguousarray(_wrap_cols(self.small_maps, c0, r0, w, h))
        return cv2.remap(self.source, m, None, cv2.INTER_NEAREST)  # type: ignore[call-overload, unused-ignore]

    def colour(self, u0: int, v0: int, w: int, h: int) -> Image:
        """Full-resolution colour of the box (u0, v0, w, h); columns wrap around on a panorama."""
        if self.maps is None:
            return np.ascontiguousarray(_wrap_cols(self.source, u0, v0, w, h))
        m1 = np.ascontiguousarray(_wrap_cols(self.maps[0], u0, v0, w, h))
        m2 = np.ascontiguousarray(_wrap_cols(self.maps[1], u0, v0, w, h))
        return cv2.remap(self.source, m1, m2, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)


class Unwarper:
    """Turns annular frames of one lens into panoramas.

    Args:
        model: the calibrated annular model (image size, centre, radial polynomial, panorama size).
        scale: reduction of the colour panorama (2: half resolution).
    """

    def __init__(self, model: AnnularModel, scale: int = 2) -> None:
        self.model = model
        self.scale = scale
        map_x, map_y = model.unwarp_maps()
        self._m1, self._m2 = cv2.convertMaps(map_x, map_y, cv2.CV_16SC2)
        # Colour: sample the centre of each scale x scale block of panorama pixels.
        off = (scale - 1) / 2.0
        vv, uu = np.mgrid[0 : model.pano_h // scale, 0 : model.pano_w // scale].astype(np.float64)
        sx, sy = model.annular_from_pano(uu * scale + off, vv * scale + off)
        self._s1, _ = cv2.convertMaps(sx.astype(np.float32), sy.astype(np.float32), cv2.CV_16SC2, nninterpolation=True)
        # The same samples as flat indices into the frame's pixels (for reading a few of them).
        x, y = self._s1[..., 0].astype(np.int64), self._s1[..., 1].astype(np.int64)
        inside = bool(((x >= 0) & (x < model.image_w) & (y >= 0) & (y < model.image_h)).all())
        self._s_index = (y * model.image_w + x).astype(np.int32).ravel() if inside else None

    @property
    def pano_size(self) -> tuple[int, int]:
        """(width, height) of the panorama."""
        return self.model.pano_w, self.model.pano_h

    def _check(self, annular: Image) -> None:
        h, w = annular.shape[:2]
        if (w, h) != (self.model.image_w, self.model.image_h):
            raise SourceError(
                f"frame is {w}x{h} px but the camera calibration is for {self.model.image_w}x{self.model.image_h}"
            )

    def apply(self, annular: Image) -> Image:
        """The full-resolution panorama of one annular frame (grey or BGR), bilinear.

        Raises:
            SourceError: if the frame size differs from the calibrated image size.
        """
        self._check(annular)
        return cv2.remap(annular, self._m1, self._m2, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)

    def frame(self, annular: Image) -> PanoFrame:
        """What the pipeline uses of one annular BGR frame (see the module docstring).

        Raises:
            SourceError: if the frame size differs from the calibrated image size.
        """
        self._check(annular)
        grey_annular = cv2.cvtColor(annular, cv2.COLOR_BGR2GRAY)
        grey = cv2.remap(grey_annular, self._m1, self._m2, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        return PanoFrame(grey, annular, self.scale, (self._m1, self._m2), self._s1, small_index=self._s_index)
