"""``panostereo calib refine``: read, refine, write, report."""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from common.errors import ConfigError
from common.site import load_site
from panostereo.calib import DEFAULT_INSTANTS
from panostereo.calib.observe import from_recording, from_site
from panostereo.calib.refine import RefineSettings, refine
from panostereo.calib.site_out import write_refined_site

__all__ = ["format_report", "refine_site"]


def refine_site(
    site_path: str | Path,
    out: str | Path,
    *,
    fix: Sequence[str] = (),
    frames: int = DEFAULT_INSTANTS,
    recording: str | Path | None = None,
    settings: RefineSettings | None = None,
) -> dict[str, Any]:
    """Refine a site's camera poses and write the refined site under ``out``; returns the report.

    Raises:
        ConfigError: a bad site or recording, an unknown ``--fix`` camera, ``--frames`` < 0, no camera to refine.
    """
    if frames < 0:
        raise ConfigError(f"--frames must be >= 0 (0: all), got {frames}")
    began = time.process_time()
    site = load_site(site_path)
    if recording is None:
        if site.dataset is None:
            raise ConfigError(
                f"{site.path}: not a dataset site (no [dataset] table): pass --recording REC.mcap, "
                "a recording of this site made with `panostereo agent record`"
            )
        cams, notes = from_site(site, frames)
    else:
        cams, notes = from_recording(recording, site, frames)
    ids = [c.sensor_id for c in cams]
    unknown = sorted(set(fix) - set(ids))
    if unknown:
        raise ConfigError(
            f"--fix {', '.join(unknown)}: not a camera with a calibration here (cameras: {', '.join(ids)})"
        )
    if len(cams) < 2:  # noqa: PLR2004 - a pose needs another camera's view of the same people
        raise ConfigError(
            f"{site.path}: {len(cams)} camera(s) with a calibration to refine; need two or more ({notes})"
        )
    result = refine(cams, fix, settings)
    refined = {
        c.sensor_id: p for c, p, r in zip(cams, result.poses, result.cameras, strict=True) if r.status == "refined"
    }
    models = {c.sensor_id: c.info.model for c in cams}
    written = write_refined_site(site, refined, models, out)
    return {
        "site": str(written),
        "source": str(recording) if recording is not None else "detection files",
        "fixed": list(fix),
        "instants": int(max((int(c.instant.max()) + 1 for c in cams if c.n), default=0)),
        "rounds": result.rounds,
        "cpu_s": round(time.process_time() - began, 2),
        "cameras": [r.to_dict() for r in result.cameras],
        "left_out": notes,
    }


def _num(x: Any, fmt: str) -> str:
    return "-" if x is None or (isinstance(x, float) and not math.isfinite(x)) else format(x, fmt)


def format_report(report: dict[str, Any]) -> str:
    """The report as a table, one camera a line."""
    lines = [
        f"refined site: {report['site']}  ({report['rounds']} rounds, {report['cpu_s']} s CPU)",
        f"{'camera':<12} {'status':<13} {'moved m':>8} {'turned deg':>10} {'residual m':>15} {'residual px':>13} "
        f"{'people':>7}",
    ]
    for c in report["cameras"]:
        res_m = f"{_num(c['residual_before_m'], '.3f')} -> {_num(c['residual_after_m'], '.3f')}"
        res_px = f"{_num(c['residual_before_px'], '.1f')} -> {_num(c['residual_after_px'], '.1f')}"
        lines.append(
            f"{c['sensor_id']:<12} {c['status']:<13} {_num(c['moved_m'], '.3f'):>8} {_num(c['turned_deg'], '.2f'):>10} "
            f"{res_m:>15} {res_px:>13} {c['people']:>7}"
        )
        if c["note"] and c["status"] != "fixed":
            lines.append(f"  {c['sensor_id']}: {c['note']}")
    lines += [f"  left out: {n}" for n in report["left_out"]]
    return "\n".join(lines)
