"""Run every ``benchmarks/bench_*.py`` as ``python -m benchmarks.<name>`` and print their JSON.

Usage::

    python -m benchmarks.run_all [--only PATTERN] [--timeout-s S]

Prints one JSON object ``{"<name>": <that benchmark's JSON object>, ...}``; a benchmark that fails or
prints no JSON appears as ``{"error": ..., "returncode": ...}`` and makes the exit code 1.
"""

from __future__ import annotations

import argparse
import fnmatch
import json
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
REPO = HERE.parent


LONGER_S = {"bench_agreement": 1800.0, "bench_calib": 3600.0, "bench_zones": 1200.0}
"""Benchmarks that need longer than ``--timeout-s`` by design (bench_agreement: 22 site replays; bench_calib: 31
refinements and 65 site replays; bench_zones: three runs of a 64-camera hall, one with five failovers)."""
ONLY_BY_NAME = ("bench_soak",)
"""Benchmarks that run for an hour: only when ``--only`` names them."""


def discover(pattern: str = "*") -> list[str]:
    """Module names of the benchmarks, sorted (those of ``ONLY_BY_NAME`` only when the pattern is their name)."""
    return sorted(
        p.stem
        for p in HERE.glob("bench_*.py")
        if fnmatch.fnmatch(p.stem, pattern) and (p.stem not in ONLY_BY_NAME or pattern == p.stem)
    )


def parse_json_object(text: str) -> dict[str, Any] | None:
    """The JSON object a benchmark printed: the whole output, else the last line that is one."""
    text = text.strip()
    try:
        value = json.loads(text)
        return value if isinstance(value, dict) else None
    except json.JSONDecodeError:
        pass
    for line in reversed(text.splitlines()):
        try:
            value = json.loads(line)
        except json.JSONDecodeError:
            continue
        if isinstance(value, dict):
            return value
    return None


def run_one(name: str, timeout_s: float) -> dict[str, Any]:
    t0 = time.monotonic()
    try:
        proc = subprocess.run(
            [sys.executable, "-m", f"benchmarks.{name}"],
            cwd=REPO,
            capture_output=True,
            text=True,
            timeout=timeout_s,
            check=False,
        )
    except subprocess.TimeoutExpired:
        return {"error": f"timed out after {timeout_s:g} s", "returncode": None}
    result = parse_json_object(proc.stdout)
    if proc.returncode != 0 or result is None:
        tail = (proc.stderr or proc.stdout).strip().splitlines()[-5:]
        return {"error": " | ".join(tail) or "no JSON object printed", "returncode": proc.returncode}
    result.setdefault("wall_s", round(time.monotonic() - t0, 2))
    return result


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m benchmarks.run_all", description=__doc__.split("\n\n")[0])
    p.add_argument("--only", default="*", metavar="PATTERN", help="run only benchmarks matching (e.g. 'bench_tr*')")
    p.add_argument("--timeout-s", type=float, default=600.0, help="per-benchmark time limit")
    args = p.parse_args(argv)
    names = discover(args.only)
    if not names:
        sys.stderr.write(f"no benchmark matches {args.only!r}\n")
        return 1
    results: dict[str, Any] = {}
    for name in names:
        sys.stderr.write(f"running {name} ...\n")
        results[name] = run_one(name, max(args.timeout_s, LONGER_S.get(name, 0.0)))
    sys.stdout.write(json.dumps(results, indent=2) + "\n")
    return 1 if any("error" in r for r in results.values()) else 0


if __name__ == "__main__":
    sys.exit(main())
