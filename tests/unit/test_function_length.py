"""No function over about 80 lines (docs/STYLE.md habit 3), checked by parsing every module with ``ast``.

A function's length runs from its ``def`` line to its last line, docstring and comments included: what a
reader has to hold at once. Nested functions count on their own and inside the function that holds them.
The packages in :data:`CHECKED` hold to it with no exception; a package joins the list once its long
functions are split.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from tests.support import REPO

MAX_LINES = 80
"""Longest a function may be (habit 3: "a function under about 80")."""

CHECKED = ("common", "sim", "sensor_node", "resource_manager", "user_agent", "panostereo")
"""Packages checked, every module in them (no exclusions)."""


def _long_functions(root: Path, package: str) -> list[str]:
    found = []
    for path in sorted((root / package).rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        for node in ast.walk(tree):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                lines = (node.end_lineno or node.lineno) - node.lineno + 1
                if lines > MAX_LINES:
                    found.append(f"{path.relative_to(root).as_posix()}:{node.lineno} {node.name}: {lines} lines")
    return found


@pytest.mark.parametrize("package", CHECKED)
def test_no_function_over_max_lines(package: str) -> None:
    assert _long_functions(REPO, package) == [], f"functions over {MAX_LINES} lines: split them"


@pytest.mark.parametrize(("body_lines", "found"), [(MAX_LINES - 1, False), (MAX_LINES, True)])
def test_the_check_counts_from_def_to_last_line(tmp_path: Path, body_lines: int, found: bool) -> None:
    (tmp_path / "pkg").mkdir()
    body = "\n".join(f"    x{i} = {i}" for i in range(body_lines))
    (tmp_path / "pkg" / "mod.py").write_text(f"def f() -> None:\n{body}\n", encoding="utf-8")
    expected = [f"pkg/mod.py:1 f: {MAX_LINES + 1} lines"] if found else []
    assert _long_functions(tmp_path, "pkg") == expected
