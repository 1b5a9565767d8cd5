"""Tests mirror the tree (docs/STYLE.md habit 15): ``pkg/sub/mod.py`` is tested in ``tests/unit/pkg/sub/test_mod.py``.

Checked both ways for the packages in :data:`PACKAGES`: every library module has its test file, and every
``test_*.py`` under ``tests/unit/<package>/`` names a module that exists (a test file left behind by a move or a
rename fails here), apart from the few in :data:`ACROSS_MODULES`, which score a whole stage chain.

``__main__.py`` files are not checked: each only calls its package's ``cli.main()``.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.support import REPO

PACKAGES = ("common", "resource_manager", "user_agent", "panostereo", "sim", "sensor_node")
UNIT = REPO / "tests" / "unit"

NOT_TESTED_BY_DESIGN = {
    # Thin entry points: argparse, config, logging, then run(); started as real processes by tests/integration.
    "resource_manager/cli.py",
    "sensor_node/cli.py",
    "user_agent/cli.py",
    "panostereo/commands/router.py",
    "panostereo/commands/up.py",
    # A shell that owns a zenoh session (habit 2): tested on loopback by tests/integration.
    "user_agent/live.py",
    # Type aliases only (numpy array types for annotations): nothing runs, mypy checks their use.
    "common/arrays.py",
    # One import point re-exporting common.annular, common.cylindrical and common.pinhole (tested there).
    "common/cameras.py",
}

NO_DIRECT_TEST: set[str] = set()
"""Library modules still without a test file of their own (exercised only through other modules' tests).
Each one here is a debt: write its test, then take it off this list. Empty: every module has its test file."""

ACROSS_MODULES = {
    # The node's whole image pipeline scored on pixels (rendered people, synthetic perspective frames, a cut of
    # a real clip): each checks what a chain of stages gives, not one module.
    "tests/unit/sensor_node/test_quality_heads.py",
    "tests/unit/sensor_node/test_quality_rendered.py",
    "tests/unit/sensor_node/test_real_pixels.py",
}


def _modules() -> list[str]:
    found = []
    for pkg in PACKAGES:
        for path in sorted((REPO / pkg).rglob("*.py")):
            if path.name not in ("__init__.py", "__main__.py"):
                found.append(path.relative_to(REPO).as_posix())
    return found


def _test_file(module: str) -> Path:
    path = Path(module)
    return UNIT / path.parent / f"test_{path.name}"


def test_every_module_has_its_mirrored_test_file() -> None:
    missing = [m for m in _modules() if m not in NOT_TESTED_BY_DESIGN | NO_DIRECT_TEST and not _test_file(m).is_file()]
    assert missing == [], "no test file beside these modules: " + ", ".join(
        f"{m} -> {_test_file(m).relative_to(REPO).as_posix()}" for m in missing
    )


def test_every_test_file_names_a_module() -> None:
    modules = {_test_file(m) for m in _modules()}
    orphans = [
        t.relative_to(REPO).as_posix()
        for pkg in PACKAGES
        for t in sorted((UNIT / pkg).rglob("test_*.py"))
        if t not in modules and t.relative_to(REPO).as_posix() not in ACROSS_MODULES
    ]
    assert orphans == [], f"test files that mirror no module: {orphans}"


@pytest.mark.parametrize("module", sorted(NOT_TESTED_BY_DESIGN | NO_DIRECT_TEST))
def test_the_allow_lists_hold_only_untested_modules_that_exist(module: str) -> None:
    """An entry stays only while it is needed: once its test file exists (or the module is gone) it must go."""
    assert (REPO / module).is_file(), f"{module} is allow-listed but does not exist"
    assert not _test_file(module).is_file(), f"{module} has its test file now: take it off the allow-list"
