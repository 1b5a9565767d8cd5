"""No function in the manager's library code is longer than :data:`MAX_LINES` (STYLE.md habit 3: one stage, one
module, read at a sitting): checked by parsing every module with ``ast``, decorators and docstrings included."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from tests.support import REPO

MAX_LINES = 80
"""The longest a function may be, from its ``def`` (or first decorator) to its last line."""

CHECKED = ("resource_manager",)


def long_functions(root: Path, packages: tuple[str, ...], max_lines: int) -> list[str]:
    """``path:line name (n lines)`` of every function longer than ``max_lines`` under ``packages``."""
    out: list[str] = []
    for package in packages:
        for path in sorted((root / package).rglob("*.py")):
            tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
            for node in ast.walk(tree):
                if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef) and node.end_lineno is not None:
                    first = min([node.lineno, *(d.lineno for d in node.decorator_list)])
                    n = node.end_lineno - first + 1
                    if n > max_lines:
                        out.append(f"{path.relative_to(root)}:{node.lineno} {node.name} ({n} lines)")
    return out


def test_no_manager_function_is_longer_than_the_limit() -> None:
    assert long_functions(REPO, CHECKED, MAX_LINES) == []


@pytest.mark.parametrize(("body_lines", "flagged"), [(3, False), (10, True)])
def test_the_check_sees_a_long_function(tmp_path: Path, body_lines: int, flagged: bool) -> None:
    (tmp_path / "pkg").mkdir()
    body = "".join("    x = 1\n" for _ in range(body_lines))
    (tmp_path / "pkg" / "m.py").write_text(f"@staticmethod\ndef f():\n{body}")
    assert bool(long_functions(tmp_path, ("pkg",), 8)) is flagged
