"""Every document the code cites (``docs/*.md``) is in the repository, and so is the licence pyproject names."""

from __future__ import annotations

import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
CITED = re.compile(r"\bdocs/[\w./-]+\.md\b")


def test_every_cited_doc_exists() -> None:
    cited: dict[str, str] = {}
    for path in sorted(REPO.glob("*/**/*.py")):
        if ".venv" in path.parts:
            continue
        for name in CITED.findall(path.read_text(encoding="utf-8")):
            cited.setdefault(name, path.relative_to(REPO).as_posix())
    assert cited, "no citation found: the pattern is out of date"
    missing = {name: where for name, where in cited.items() if not (REPO / name).is_file()}
    assert not missing, f"cited but not in the repository: {missing}"


def test_the_licence_pyproject_names_is_there() -> None:
    assert 'license = "Apache-2.0"' in (REPO / "pyproject.toml").read_text(encoding="utf-8")
    assert "Apache License" in (REPO / "LICENSE").read_text(encoding="utf-8")
