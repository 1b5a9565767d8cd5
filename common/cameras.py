"""Camera models of the paper, one import point: cylindrical, annular (PAL), pinhole and PTZ.

The implementations live in one module per model (kept under ~400 lines each):

* :mod:`common.cylindrical` -- the 4-parameter cylindrical virtual camera (Step 3)
  and its least-squares calibration from >= 3 known points;
* :mod:`common.annular` -- annular (PAL) image <-> panorama (Steps 1-2): ring centre
  from vertical lines, 2nd-order radial polynomial, ``cv2.remap`` maps, and
  :func:`design_pal`, a PAL-like lens for the simulator;
* :mod:`common.pinhole` -- perspective cameras (K, distortion, R, t or a 3x4 P)
  and PTZ heads.

All are pure (numpy only); the remap maps are float32 arrays for ``cv2.remap``.
"""

from __future__ import annotations

from common.annular import AnnularModel, center_from_lines, design_pal, fit_radial_polynomial
from common.cylindrical import CylindricalCalibration, CylindricalCamera, calibrate_cylindrical
from common.pinhole import PinholeCamera, PtzCamera, rotation_from_rvec

__all__ = [
    "AnnularModel",
    "CylindricalCalibration",
    "CylindricalCamera",
    "PinholeCamera",
    "PtzCamera",
    "calibrate_cylindrical",
    "center_from_lines",
    "design_pal",
    "fit_radial_polynomial",
    "rotation_from_rvec",
]
