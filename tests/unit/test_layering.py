"""Layering: who may import whom, checked by parsing every module's imports with ``ast``.

Rules (docs/STYLE.md habit 2):

* ``common`` imports no tier, not ``sim`` and not ``panostereo``;
* ``sim`` (the simulator) imports only ``common``, of the project's packages;
* a tier (``sensor_node``, ``resource_manager``, ``user_agent``) imports no other tier, not ``panostereo`` and
  not ``sim``: the simulated camera reaches the sensor node through its source registry
  (``panostereo.sim_camera``, an entry point), so only ``panostereo``'s tools, the benchmarks and the tests
  (not checked here) import ``sim``;
* only the shells import ``zenoh`` or ``mcap``: the files in :data:`SHELLS` below. Pure stages stay testable
  without a network or a recorder.

Imports inside functions count too, and so do ``importlib.import_module("x")`` / ``__import__("x")`` calls
with a literal name.
"""

from __future__ import annotations

import ast
import fnmatch
from dataclasses import dataclass
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]

TIERS = ("sensor_node", "resource_manager", "user_agent")
PACKAGES = ("common", "sim", *TIERS, "panostereo")


TRANSPORT_LIBS = ("zenoh", "mcap")
"""Third-party libraries only the shells may import."""

# The allow-list: paths (relative to the repo, fnmatch patterns) that may import zenoh or mcap.
SHELLS = (
    "common/session.py",  # opens sessions
    "common/transport.py",  # typed publish/subscribe
    "*/node.py",  # each tier's process shell
    "*/cli.py",  # entry points
    "user_agent/client.py",  # the agent's zenoh client
    "user_agent/record.py",  # MCAP recorder
    "user_agent/replay.py",  # MCAP replay
    "user_agent/recording.py",  # MCAP reader: the recorder's counterpart (file I/O, not a pure stage)
    "panostereo/*",  # the umbrella command may import anything
    "panostereo/**/*",
)


@dataclass(frozen=True)
class Violation:
    path: str
    line: int
    imported: str
    rule: str

    def __str__(self) -> str:
        return f"{self.path}:{self.line}: imports {self.imported} ({self.rule})"


def imported_modules(tree: ast.AST, package: str) -> list[tuple[str, int]]:
    """Absolute names of every module a file imports (relative imports resolved against ``package``)."""
    out: list[tuple[str, int]] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(alias.name, node.lineno) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: max(0, len(package.split(".")) - node.level + 1)]
                name = ".".join([*base, node.module] if node.module else base)
            else:
                name = node.module or ""
            out.append((name, node.lineno))
        elif (
            isinstance(node, ast.Call)
            and node.args
            and isinstance(node.args[0], ast.Constant)
            and isinstance(node.args[0].value, str)
            and (
                (isinstance(node.func, ast.Attribute) and node.func.attr == "import_module")
                or (isinstance(node.func, ast.Name) and node.func.id in ("__import__", "import_module"))
            )
        ):
            out.append((node.args[0].value, node.lineno))
    return out


def is_shell(rel: str) -> bool:
    return any(fnmatch.fnmatch(rel, pattern) for pattern in SHELLS)


def check_tree(root: Path) -> tuple[list[Violation], int]:
    """All layering violations under ``root``, and how many files were checked."""
    violations: list[Violation] = []
    files = 0
    for top in PACKAGES:
        for path in sorted((root / top).rglob("*.py")):
            rel = path.relative_to(root).as_posix()
            files += 1
            package = ".".join(path.relative_to(root).with_suffix("").parts[:-1])
            tree = ast.parse(path.read_text(encoding="utf-8"), filename=rel)
            for name, line in imported_modules(tree, package):
                head = name.split(".")[0]
                if top == "common" and head in (*TIERS, "sim", "panostereo"):
                    violations.append(Violation(rel, line, name, "common imports no tier, not sim, not panostereo"))
                elif top == "sim" and head in (*TIERS, "panostereo"):
                    violations.append(Violation(rel, line, name, "sim imports only common"))
                elif top in TIERS and head in (*TIERS, "panostereo") and head != top:
                    violations.append(Violation(rel, line, name, "tiers never import each other nor panostereo"))
                elif top in TIERS and head == "sim":
                    violations.append(Violation(rel, line, name, "tiers never import sim"))
                if head in TRANSPORT_LIBS and not is_shell(rel):
                    violations.append(Violation(rel, line, name, "only shells import zenoh/mcap (see SHELLS)"))
    return violations, files


def test_repository_layering() -> None:
    violations, files = check_tree(REPO)
    assert files > 10, "found too few modules: is REPO right?"
    assert (REPO / "sim" / "world.py").is_file(), "the simulator's package moved: update the rules"
    assert not violations, "layering violations:\n" + "\n".join(map(str, violations))


# -- the checker itself catches what it should (so the test above can fail) ---------


def _write(root: Path, rel: str, text: str) -> None:
    p = root / rel
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(text)


@pytest.mark.parametrize(
    ("rel", "source", "rule"),
    [
        ("common/geo.py", "import sensor_node.segmentation.blobs\n", "common imports no tier"),
        ("common/geo.py", "from panostereo import cli\n", "common imports no tier"),
        ("common/geo.py", "def f():\n    import zenoh\n", "only shells"),
        ("common/geo.py", "import importlib\nimportlib.import_module('resource_manager.track')\n", "common imports"),
        ("sensor_node/segmentation/blobs.py", "from resource_manager.stereo.match import x\n", "tiers never import"),
        ("sensor_node/segmentation/blobs.py", "from mcap.writer import Writer\n", "only shells"),
        ("user_agent/views.py", "import zenoh.ext\n", "only shells"),
        ("user_agent/views.py", "from panostereo.launcher import x\n", "tiers never import"),
        ("resource_manager/sub/x.py", "from ...sensor_node import blobs\n", "tiers never import"),
        ("common/geo.py", "from sim.world import World\n", "common imports no tier, not sim"),
        ("sim/world.py", "from sensor_node.pipeline import ImagePipeline\n", "sim imports only common"),
        ("sim/render/cameras.py", "def f():\n    import panostereo.cli\n", "sim imports only common"),
        ("sim/source.py", "import zenoh\n", "only shells"),
        ("sensor_node/node.py", "from sim.source import SimFrames\n", "tiers never import sim"),
        ("sensor_node/pipeline.py", "import sim.render.cameras\n", "tiers never import sim"),
        ("sensor_node/build.py", "def f():\n    from sim.source import SimFrames\n", "tiers never import sim"),
        ("user_agent/views.py", "from sim.world import World\n", "tiers never import sim"),
        ("resource_manager/plan/p.py", "from sim.driver import goals_from_plans\n", "tiers never import sim"),
    ],
)
def test_checker_flags_violations(tmp_path: Path, rel: str, source: str, rule: str) -> None:
    _write(tmp_path, rel, source)
    violations, _ = check_tree(tmp_path)
    assert len(violations) == 1, violations
    assert rule in violations[0].rule
    assert violations[0].path == rel


@pytest.mark.parametrize(
    ("rel", "source"),
    [
        ("common/session.py", "import zenoh\n"),
        ("common/transport.py", "import zenoh\n"),
        ("sensor_node/node.py", "import zenoh\nfrom common import keys\n"),
        ("resource_manager/cli.py", "import zenoh\n"),
        ("user_agent/record.py", "from mcap.writer import Writer\n"),
        ("user_agent/replay.py", "import mcap\n"),
        ("user_agent/client.py", "import zenoh\n"),
        ("panostereo/commands/up.py", "import zenoh\nimport sensor_node.cli\nimport resource_manager.node\n"),
        ("sensor_node/segmentation/blobs.py", "from ..background import model\nfrom . import groups\nimport numpy\n"),
        ("common/geo.py", "from common import schema\nimport zenoh_like_name\n"),
        ("sim/source.py", "from common.frames import Frame\nfrom sim.world import World\nimport cv2\n"),
        ("panostereo/sim_camera.py", "from sensor_node.build import NodeParts\nfrom sim.source import SimFrames\n"),
        ("panostereo/commands/demo.py", "from sim.world import write_gt_csv\n"),
    ],
)
def test_checker_allows_shells_and_own_package(tmp_path: Path, rel: str, source: str) -> None:
    _write(tmp_path, rel, source)
    violations, _ = check_tree(tmp_path)
    assert violations == []


# -- the manager's stages (resource_manager/): no import circles, one owner of a track's state ---------------

TRACK_FIELDS = frozenset({"logodds", "height_var", "confirmed", "detected", "links", "looks", "look_s", "misses"})
"""Fields of :class:`resource_manager.track.state.TrackRecord` no other record has: assigning one outside
``resource_manager/track/`` means another stage reaches into a track."""


def manager_import_graph(root: Path) -> dict[str, set[str]]:
    """resource_manager module -> the resource_manager modules it imports (module level and inside functions)."""
    graph: dict[str, set[str]] = {}
    base = root / "resource_manager"
    for path in sorted(base.rglob("*.py")):
        rel = path.relative_to(root).with_suffix("")
        name = ".".join(rel.parts)
        package = ".".join(rel.parts[:-1])
        tree = ast.parse(path.read_text(encoding="utf-8"))
        deps: set[str] = set()
        for imported, _ in imported_modules(tree, package):
            if imported.startswith("resource_manager"):
                deps.add(imported)
        for node in ast.walk(tree):  # "from resource_manager import wiring" imports the module wiring
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("resource_manager"):
                deps.update(f"{node.module}.{alias.name}" for alias in node.names)
        graph[name] = deps
    # Keep the names that are modules; a name inside a module (a class) counts as that module.
    return {m: {d if d in graph else d.rsplit(".", 1)[0] for d in ds} - {m} for m, ds in graph.items()}


def find_cycle(graph: dict[str, set[str]]) -> list[str]:
    """One import circle of the graph, or []."""
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node: str) -> list[str]:
        state[node] = 1
        stack.append(node)
        for dep in sorted(graph.get(node, ())):
            if state.get(dep) == 1:
                return [*stack[stack.index(dep) :], dep]
            if dep in graph and dep not in state and (found := visit(dep)):
                return found
        stack.pop()
        state[node] = 2
        return []

    for node in sorted(graph):
        if node not in state and (found := visit(node)):
            return found
    return []


def track_state_writes(root: Path) -> list[str]:
    """``file:line`` of every assignment to a track-only field outside resource_manager/track/."""
    out = []
    for path in sorted((root / "resource_manager").rglob("*.py")):
        rel = path.relative_to(root).as_posix()
        if rel.startswith("resource_manager/track/"):
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target] if isinstance(
                node, ast.AugAssign | ast.AnnAssign) else []  # fmt: skip
            for target in targets:
                t = target
                while isinstance(t, ast.Subscript):
                    t = t.value
                if isinstance(t, ast.Attribute) and t.attr in TRACK_FIELDS:
                    out.append(f"{rel}:{node.lineno}")
    return out


def test_manager_stages_have_no_import_circles_and_one_owner_of_track_state() -> None:
    graph = manager_import_graph(REPO)
    assert {"resource_manager.track.tracker", "resource_manager.ingest.schedule"} <= set(graph)
    assert find_cycle(graph) == []
    assert track_state_writes(REPO) == []


def test_the_manager_checks_catch_circles_and_outside_writes(tmp_path: Path) -> None:
    _write(tmp_path, "resource_manager/a.py", "from resource_manager.b import x\n")
    _write(tmp_path, "resource_manager/b.py", "def f():\n    from resource_manager import a\n")
    _write(tmp_path, "resource_manager/plan/p.py", "def f(tr):\n    tr.logodds = 0.0\n    tr.looks['c'] += 1\n")
    _write(tmp_path, "resource_manager/track/t.py", "def f(tr):\n    tr.logodds = 0.0\n")
    assert find_cycle(manager_import_graph(tmp_path)) in (
        ["resource_manager.a", "resource_manager.b", "resource_manager.a"],
        ["resource_manager.b", "resource_manager.a", "resource_manager.b"],
    )
    assert track_state_writes(tmp_path) == ["resource_manager/plan/p.py:2", "resource_manager/plan/p.py:3"]
