"""Write a refined site: the same site, with its cameras' calibrations replaced.

The site file, every process config and every file they name by a relative path (detection files, calibrations,
ground truth, the simulated world) are copied under ``DIR`` keeping their layout relative to one another, so the
copy runs as the original does (``panostereo evaluate-site``, ``demo --site``, ``up``). Then, per refined camera:

* a pinhole camera: its calibration JSON (the node's ``[source]`` or ``[camera] calibration``) gets the new
  ``R`` and ``t`` (its intrinsics and distortion as they were);
* a level camera (panoramic, PTZ head): the node config's ``[pose]`` table gets the new ``x_m``, ``y_m``,
  ``z_m`` and ``yaw_deg``; every other line of the file, comments included, is kept.
"""

from __future__ import annotations

import json
import math
import os
import re
import shutil
import tomllib
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

from common.config import resolve_path
from common.errors import ConfigError
from common.site import SiteConfig
from panostereo.calib.poses import CameraPose

__all__ = ["write_refined_site"]

MAX_PATH_CHARS = 4096
"""A config string longer than this is no path."""
_KEY_LINE = re.compile(r"^(\s*)(x_m|y_m|z_m|yaw_deg)(\s*=\s*)([^#\n]*?)(\s*(#.*)?)$")


def _strings(value: Any) -> Iterator[str]:
    if isinstance(value, str):
        yield value
    elif isinstance(value, Mapping):
        for v in value.values():
            yield from _strings(v)
    elif isinstance(value, list):
        for v in value:
            yield from _strings(v)


def _read_toml(path: Path) -> dict[str, Any]:
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, tomllib.TOMLDecodeError) as err:
        raise ConfigError(f"{path}: cannot read: {err}") from err


def _referenced(config: Path) -> list[Path]:
    """Files a TOML config names by a relative path (resolved against its folder), that exist."""
    out = []
    for s in _strings(_read_toml(config)):
        if not s or os.path.isabs(s) or "\n" in s or len(s) > MAX_PATH_CHARS:
            continue
        p = Path(resolve_path(config, s))
        if p.is_file():
            out.append(p.resolve())
    return out


def _pose_table(text: str, pose: CameraPose, source: str) -> str:
    """``text`` with its ``[pose]`` table's x_m, y_m, z_m and yaw_deg replaced (the others kept)."""
    values = {
        "x_m": f"{pose.centre_m[0]:.4f}",
        "y_m": f"{pose.centre_m[1]:.4f}",
        "z_m": f"{pose.centre_m[2]:.4f}",
        "yaw_deg": f"{math.degrees(pose.yaw_rad):.4f}",
    }
    lines = text.splitlines(keepends=True)
    out: list[str] = []
    in_pose, seen = False, set()
    for line in lines:
        stripped = line.strip()
        if stripped.startswith("["):
            if in_pose:
                out.extend(f"{k} = {v}\n" for k, v in values.items() if k not in seen)
            in_pose = stripped.split("#", 1)[0].strip() == "[pose]"
        elif in_pose and (m := _KEY_LINE.match(line.rstrip("\n"))):
            seen.add(m.group(2))
            out.append(f"{m.group(1)}{m.group(2)}{m.group(3)}{values[m.group(2)]}{m.group(5)}\n")
            continue
        out.append(line)
    if in_pose:
        out.extend(f"{k} = {v}\n" for k, v in values.items() if k not in seen)
    if not any(line.strip().split("#", 1)[0].strip() == "[pose]" for line in lines):
        raise ConfigError(f"{source}: no [pose] table to refine")
    return "".join(out)


def _calibration_json(original: Path, pose: CameraPose, k: list[float], dist: list[float], size: list[int]) -> str:
    try:
        data = json.loads(original.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError) as err:
        raise ConfigError(f"{original}: cannot read the calibration: {err}") from err
    if not isinstance(data, dict):
        raise ConfigError(f"{original}: expected a JSON object")
    for key in ("P", "rvec"):
        data.pop(key, None)
    data.update(
        model="pinhole",
        image_size=size,
        K=[k[0:3], k[3:6], k[6:9]],
        dist=dist,
        R=pose.rotation.tolist(),
        t=pose.t_m.tolist(),
    )
    return json.dumps(data, indent=1) + "\n"


def write_refined_site(
    site: SiteConfig,
    refined: Mapping[str, CameraPose],
    models: Mapping[str, Any],
    out: str | Path,
) -> Path:
    """Copy the site under ``out`` with the ``refined`` poses (sensor id -> pose); ``models`` holds each pinhole
    camera's ``PinholeModel`` (its intrinsics). Returns the refined site file.

    Raises:
        ConfigError: ``out`` inside the site, a process config that cannot be read, or a camera whose
            calibration cannot be found in its node config.
    """
    site_path = Path(site.path).resolve()
    configs = {p.name: Path(site.resolve(p.config)).resolve() for p in site.process}
    files = {site_path, *configs.values()}
    for cfg in configs.values():
        files.update(_referenced(cfg))
    if site.dataset is not None and site.dataset.ground_truth:
        gt = Path(site.resolve(site.dataset.ground_truth)).resolve()
        if gt.is_file():
            files.add(gt)
    root = Path(os.path.commonpath([str(f.parent) for f in files]))
    dst = Path(out).resolve()
    if dst == root or (root in dst.parents and any(dst in f.parents or f.parent == dst for f in files)):
        raise ConfigError(f"--out {out}: must not hold the site's own files (it is inside {root})")
    dst.mkdir(parents=True, exist_ok=True)
    for f in files:
        target = dst / f.relative_to(root)
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(f, target)
    for name, cfg in configs.items():
        raw = _read_toml(cfg)
        if "node" not in raw:
            continue
        sid = str(raw["node"].get("id", name))
        if sid not in refined:
            continue
        pose = refined[sid]
        target_cfg = dst / cfg.relative_to(root)
        if pose.level:
            target_cfg.write_text(_pose_table(cfg.read_text(encoding="utf-8"), pose, str(cfg)), encoding="utf-8")
            continue
        calib = raw.get("source", {}).get("calibration") or raw.get("camera", {}).get("calibration")
        if not calib:
            raise ConfigError(f"{cfg}: camera {sid!r} names no calibration JSON to refine")
        original = Path(resolve_path(cfg, calib)).resolve()
        model = models[sid]
        text = _calibration_json(original, pose, list(model.k), list(model.dist), [model.width_px, model.height_px])
        (dst / original.relative_to(root)).write_text(text, encoding="utf-8")
    return dst / site_path.relative_to(root)
