"""Common calibration formats -> the project's pinhole calibration JSON (pure: numpy, xml, cv2.FileStorage).

The project's form (:meth:`common.cameras.PinholeCamera.from_calibration`)::

    {"model": "pinhole", "image_size": [w, h], "K": 3x3, "dist": [...], "R": 3x3, "t": [3]}

world -> camera (``x_cam = R x_world + t``), metres, OpenCV's distortion model.

* **Tsai** (the PETS 2009 XML: ``Geometry`` width height dpx dpy, ``Intrinsic``
  focal kappa1 cx cy sx, ``Extrinsic`` rx ry rz tx ty tz, millimetres):
  ``K = [[sx f / dpx, 0, cx], [0, f / dpy, cy], [0, 0, 1]]``, ``R = Rz(rz) Ry(ry)
  Rx(rx)``, ``t = T / 1000``. Tsai's radial model maps the other way from
  OpenCV's: *undistorted = distorted (1 + kappa1 r_d^2)* (r_d on the sensor in
  mm). It has no exact OpenCV form; OpenCV's rational coefficients are fitted to
  it by linear least squares over the image (exact to well under 0.01 px when
  the mapping is monotonic over the image). Where it folds inside the image
  (kappa1 < 0 and a large field), only ``k1 k2 k3`` are fitted inside
  ``FOLD_FIT`` of the fold radius: beyond the fold the Tsai model itself means nothing.
* **OpenCV YAML/XML** (``cv2.FileStorage``): ``camera_matrix`` (or ``K``),
  ``distortion_coefficients`` (or ``dist_coeffs``, ``D``), ``image_width`` /
  ``image_height`` (or ``image_size``), and ``rvec`` or ``R`` (``rotation_matrix``)
  with ``tvec`` (``T``, ``translation``) in the file's units.
* **P matrix**: 12 numbers (a 3x4 projection, text or JSON) decomposed as K [R | t].
"""

from __future__ import annotations

import json
import math
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import numpy as np

from common.arrays import FloatArray
from common.errors import ConfigError
from common.pinhole import PinholeCamera, rotation_from_rvec

__all__ = ["FOLD_FIT", "calibration_json", "from_opencv_file", "from_p_matrix", "from_tsai_xml", "tsai_rotation"]

MAT3_VALUES = 9
"""Numbers in a 3x3 matrix (K, R)."""
VEC3_VALUES = 3
"""Numbers in a 3-vector (rvec, tvec)."""
SIZE_VALUES = 2
"""(width, height)."""
P_VALUES = 12
"""Numbers in a 3x4 projection matrix."""


FOLD_FIT = 0.85
"""Fraction of the fold radius inside which a folding Tsai lens is fitted."""


def tsai_rotation(rx: float, ry: float, rz: float) -> FloatArray:
    """Tsai's world -> camera rotation ``Rz(rz) Ry(ry) Rx(rx)`` (radians)."""
    cx, sx, cy, sy, cz, sz = math.cos(rx), math.sin(rx), math.cos(ry), math.sin(ry), math.cos(rz), math.sin(rz)
    r_x = np.array([[1.0, 0.0, 0.0], [0.0, cx, -sx], [0.0, sx, cx]])
    r_y = np.array([[cy, 0.0, sy], [0.0, 1.0, 0.0], [-sy, 0.0, cy]])
    r_z = np.array([[cz, -sz, 0.0], [sz, cz, 0.0], [0.0, 0.0, 1.0]])
    return r_z @ r_y @ r_x


def _attrs(root: ET.Element, name: str, keys: tuple[str, ...], source: str) -> dict[str, float]:
    el = root.find(name) if root.tag != name else root
    if el is None:
        raise ConfigError(f"{source}: Tsai XML: expected a <{name}> element, got none")
    out: dict[str, float] = {}
    for k in keys:
        if k not in el.attrib:
            raise ConfigError(f"{source}: Tsai XML: <{name}> needs attribute {k!r}, got {sorted(el.attrib)}")
        try:
            out[k] = float(el.attrib[k])
        except ValueError as err:
            raise ConfigError(f"{source}: Tsai XML: <{name}> {k}: expected a number, got {el.attrib[k]!r}") from err
    return out


def _fit_dist(k: FloatArray, size: tuple[int, int], kappa: float) -> list[float]:
    """OpenCV coefficients whose forward (undistorted -> distorted) model inverts Tsai's over the image.

    Tsai: ``r_u = r_d (1 + kappa r_d^2)`` in normalised units; OpenCV: ``r_d = r_u g(r_u^2)`` with
    ``g = (1 + k1 r^2 + k2 r^4 + k3 r^6) / (1 + k4 r^2 + k5 r^4 + k6 r^6)``, linear in the k's once
    multiplied out.
    """
    w, h = size
    u, v = np.meshgrid(np.linspace(0, w - 1, 97), np.linspace(0, h - 1, 73))
    rd2 = (((u - k[0, 2]) / k[0, 0]) ** 2 + ((v - k[1, 2]) / k[1, 1]) ** 2).ravel()
    if kappa == 0.0:
        return []
    fold = kappa < 0 and rd2.max() > -1.0 / (3.0 * kappa)
    if fold:
        rd2 = rd2[rd2 < FOLD_FIT**2 * (-1.0 / (3.0 * kappa))]
    g = 1.0 / (1.0 + kappa * rd2)  # distorted / undistorted radius
    ru2 = rd2 / g**2
    if fold:
        a = np.stack([ru2, ru2**2, ru2**3], 1)
        k1, k2, k3 = np.linalg.lstsq(a, g - 1.0, rcond=None)[0]
        return [float(k1), float(k2), 0.0, 0.0, float(k3)]
    a = np.stack([ru2, ru2**2, ru2**3, -g * ru2, -g * ru2**2, -g * ru2**3], 1)
    k1, k2, k3, k4, k5, k6 = np.linalg.lstsq(a, g - 1.0, rcond=None)[0]
    return [float(k1), float(k2), 0.0, 0.0, float(k3), float(k4), float(k5), float(k6)]


def from_tsai_xml(text: str, source: str = "Tsai XML") -> dict[str, Any]:
    """A Tsai calibration (PETS 2009 XML, millimetres) as the project's calibration dict.

    Raises:
        ConfigError: not XML, or a missing or non-numeric attribute (named).
    """
    try:
        root = ET.fromstring(text)
    except ET.ParseError as err:
        raise ConfigError(f"{source}: not XML: {err}") from err
    g = _attrs(root, "Geometry", ("width", "height", "dpx", "dpy"), source)
    i = _attrs(root, "Intrinsic", ("focal", "kappa1", "cx", "cy", "sx"), source)
    e = _attrs(root, "Extrinsic", ("tx", "ty", "tz", "rx", "ry", "rz"), source)
    if not (g["dpx"] > 0 and g["dpy"] > 0 and i["focal"] > 0 and i["sx"] > 0):
        raise ConfigError(f"{source}: Tsai XML: dpx, dpy, focal and sx must be > 0, got {g} {i}")
    k = np.array([[i["sx"] * i["focal"] / g["dpx"], 0.0, i["cx"]], [0.0, i["focal"] / g["dpy"], i["cy"]], [0, 0, 1]])
    size = (round(g["width"]), round(g["height"]))
    # kappa1 is per mm^2 on the sensor; normalised image units are sensor mm / focal.
    kappa = i["kappa1"] * i["focal"] ** 2
    return calibration_json(
        k, _fit_dist(k, size, kappa), tsai_rotation(e["rx"], e["ry"], e["rz"]),
        np.array([e["tx"], e["ty"], e["tz"]]) / 1000.0, size,
    )  # fmt: skip


def calibration_json(k: FloatArray, dist: list[float], r: FloatArray, t: FloatArray, size: tuple[int, int]) -> dict:
    """The project's calibration dict, checked by :class:`PinholeCamera` (raises ConfigError)."""
    d = {
        "model": "pinhole",
        "image_size": [int(size[0]), int(size[1])],
        "K": np.asarray(k, np.float64).tolist(),
        "dist": [float(x) for x in dist],
        "R": np.asarray(r, np.float64).tolist(),
        "t": np.asarray(t, np.float64).ravel().tolist(),
    }
    PinholeCamera.from_calibration(d, "converted calibration")
    return d


def _node(fs: Any, names: tuple[str, ...]) -> FloatArray | None:
    for n in names:
        node = fs.getNode(n)
        if node is None or node.empty():
            continue
        if node.isSeq():  # a plain list of numbers (Wildtrack's rvec, tvec)
            return np.asarray([node.at(j).real() for j in range(node.size())], np.float64)
        mat = node.mat() if node.isMap() else None
        if mat is not None:
            return np.asarray(mat, np.float64)
    return None


def _scalar(fs: Any, name: str) -> float | None:
    node = fs.getNode(name)
    if node is None or node.empty():
        return None
    return float(node.real())


def _storage(path: Path) -> dict[str, Any]:
    """The entries of an OpenCV FileStorage file the conversion knows, by role (None: absent)."""
    import cv2

    if not path.is_file():
        raise ConfigError(f"{path}: no such calibration file")
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    if not fs.isOpened():
        raise ConfigError(f"{path}: not a readable OpenCV YAML/XML file")
    try:
        return {
            "k": _node(fs, ("camera_matrix", "cameraMatrix", "K", "intrinsic", "M")),
            "dist": _node(fs, ("distortion_coefficients", "dist_coeffs", "distCoeffs", "D", "dist")),
            "rvec": _node(fs, ("rvec", "rotation_vector")),
            "rmat": _node(fs, ("R", "rotation_matrix", "rotation")),
            "tvec": _node(fs, ("tvec", "T", "translation", "t")),
            "w": _scalar(fs, "image_width"),
            "h": _scalar(fs, "image_height"),
            "size": _node(fs, ("image_size", "imageSize")),
        }
    finally:
        fs.release()


def from_opencv_file(
    path: Path, *, units_m: float = 1.0, image_size: tuple[int, int] | None = None, extrinsic: Path | None = None
) -> dict:
    """An OpenCV calibration file (YAML/XML, ``cv2.FileStorage``) as the project's calibration dict.

    Args:
        path: the file (the camera matrix, distortion, and the pose unless ``extrinsic`` is given).
        units_m: metres per unit of its translation (0.001 for mm, 0.01 for Wildtrack's cm).
        image_size: (w, h) when the file has none.
        extrinsic: a second file with the pose (``rvec``/``R`` and ``tvec``), as Wildtrack keeps them
            (``intrinsic_zero/intr_CAM.xml`` beside ``extrinsic/extr_CAM.xml``).

    Raises:
        ConfigError: unreadable file, or a missing camera matrix, pose or image size (named).
    """
    intr = _storage(path)
    pose = _storage(extrinsic) if extrinsic is not None else intr
    where = f"{extrinsic}" if extrinsic is not None else f"{path}"
    k, dist, w, h, size_node = intr["k"], intr["dist"], intr["w"], intr["h"], intr["size"]
    rvec, rmat, tvec = pose["rvec"], pose["rmat"], pose["tvec"]
    if k is None or k.size != MAT3_VALUES:
        raise ConfigError(f"{path}: expected a 3x3 camera_matrix, got {None if k is None else k.shape}")
    if rmat is not None and rmat.size == MAT3_VALUES:
        r = rmat.reshape(3, 3)
    elif rvec is not None and rvec.size == VEC3_VALUES:
        r = rotation_from_rvec(rvec.ravel())
    else:
        hint = "" if extrinsic is not None else " (or pass the file that has it: --extrinsic FILE)"
        raise ConfigError(f"{where}: expected the camera's pose: rvec (3) or R (3x3), with tvec{hint}")
    if tvec is None or tvec.size != VEC3_VALUES:
        raise ConfigError(f"{where}: expected tvec with 3 values, got {None if tvec is None else tvec.size}")
    if w is not None and h is not None:
        size = (round(w), round(h))
    elif size_node is not None and size_node.size == SIZE_VALUES:
        size = (round(float(size_node.ravel()[0])), round(float(size_node.ravel()[1])))
    elif image_size is not None:
        size = image_size
    else:
        raise ConfigError(f"{path}: no image_width/image_height: pass --image-size W H")
    coeffs = [] if dist is None else [float(x) for x in dist.ravel()]
    return calibration_json(k.reshape(3, 3), coeffs, r, tvec.ravel() * units_m, size)


def from_p_matrix(text: str, image_size: tuple[int, int], *, units_m: float = 1.0, source: str = "P") -> dict:
    """A 3x4 projection matrix (12 numbers: JSON, or whitespace/comma separated) decomposed as K [R | t].

    Raises:
        ConfigError: not 12 finite numbers, or a singular matrix.
    """
    try:
        data = json.loads(text)
        if isinstance(data, dict):
            data = data.get("P", data)
        values = np.asarray(data, np.float64).ravel()
    except (json.JSONDecodeError, ValueError, TypeError):
        try:
            values = np.asarray(text.replace(",", " ").replace(";", " ").split(), np.float64)
        except ValueError as err:
            raise ConfigError(f"{source}: expected 12 numbers (a 3x4 P matrix)") from err
    if values.size != P_VALUES:
        raise ConfigError(f"{source}: expected 12 numbers (a 3x4 P matrix), got {values.size}")
    p = values.reshape(3, 4).copy()
    p[:, 3] *= units_m
    cam = PinholeCamera.from_calibration({"model": "pinhole", "image_size": list(image_size), "P": p.tolist()}, source)
    return calibration_json(cam.k, [], cam.r, cam.t, image_size)
