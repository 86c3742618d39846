"""The house rules of spm_pin, read from its source with ``ast``.

1. No import circle between modules.
2. Imports point down the layers of the design (errors, design, rotations ->
   kinematics -> model -> closure, collision -> dynamics -> workspace, planning ->
   viz, hardware, calibration, remote, envs, optimize -> study -> cli); nothing
   imports the command line.
3. No module over 800 lines.

Imports are read at the top level and inside functions; imports under
``if TYPE_CHECKING:`` are left out (they never run), and so are the re-exports of
package ``__init__`` modules (a name imported from a package counts as imported from
the submodule that defines it), but code held in a package ``__init__`` counts. Today's
violations are listed in ``ALLOWED``: the test
fails on any violation not listed, and on any listed entry that no longer occurs, so
the list can only shrink.
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

import pytest

PACKAGE = "spm_pin"
ROOT = Path(__file__).resolve().parent.parent / PACKAGE

#: Layer of each top-level part of the package (lower numbers are lower layers).
LAYERS: dict[str, int] = {
    "_version": 0,
    "errors": 0,
    "design": 0,
    "rotations": 0,
    "_checks": 0,
    "_jit": 0,
    "kinematics": 1,
    "model": 2,
    "closure": 3,
    "collision": 3,
    "dynamics": 4,
    "workspace": 5,
    "planning": 5,
    "viz": 6,
    "hardware": 6,
    "calibration": 6,
    "remote": 6,
    "envs": 6,
    "optimize": 6,
    "demo": 7,
    "_records": 7,
    "study": 7,
    "cli": 8,
    "__main__": 9,
}
#: Longest module [lines].
MAX_LINES = 800

#: Today's violations, each to be deleted by the step that removes it.
ALLOWED: dict[str, set[object]] = {
    "circles": set(),
    "upward": set(),
    "long": set(),
}


# --------------------------------------------------------------------- reading
def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def modules() -> dict[str, Path]:
    return {module_name(path): path for path in sorted(ROOT.rglob("*.py"))}


def is_package(name: str, table: dict[str, Path]) -> bool:
    return table[name].name == "__init__.py"


def _type_checking_block(node: ast.AST) -> bool:
    if not isinstance(node, ast.If):
        return False
    test = node.test
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def _imports(tree: ast.AST) -> Iterator[ast.Import | ast.ImportFrom]:
    """Every import statement that runs (not under ``if TYPE_CHECKING:``)."""
    stack: list[ast.AST] = [tree]
    while stack:
        node = stack.pop()
        if _type_checking_block(node):
            assert isinstance(node, ast.If)
            stack.extend(node.orelse)
            continue
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            yield node
        stack.extend(ast.iter_child_nodes(node))


def _absolute(module: str, node: ast.ImportFrom, package: bool) -> str:
    if node.level == 0:
        return node.module or ""
    base = module.split(".") if package else module.split(".")[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join([*base, node.module] if node.module else base)


def _exports(package: str, table: dict[str, Path]) -> dict[str, str]:
    """Names a package ``__init__`` re-exports -> the module that defines them."""
    tree = ast.parse(table[package].read_text(encoding="utf-8"))
    found: dict[str, str] = {}
    for node in _imports(tree):
        if isinstance(node, ast.ImportFrom):
            source = _absolute(package, node, True)
            for alias in node.names:
                found[alias.asname or alias.name] = source
    return found


def _resolve(target: str, name: str | None, table: dict[str, Path]) -> str | None:
    """The spm_pin module an import of ``name`` from ``target`` reads."""
    if not target.startswith(PACKAGE):
        return None
    if name is not None and f"{target}.{name}" in table:
        return f"{target}.{name}"
    if target in table and is_package(target, table) and name is not None:
        source = _exports(target, table).get(name)
        if source is not None and source != target:
            return _resolve(source, None, table) or source
    while target and target not in table:
        target = target.rpartition(".")[0]
    return target or None


def _public(tree: ast.Module) -> set[str]:
    """The names of a module's ``__all__`` (empty if it has none)."""
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(
            isinstance(t, ast.Name) and t.id == "__all__" for t in node.targets
        ):
            value = ast.literal_eval(node.value)
            return {str(name) for name in value}
    return set()


def import_edges() -> set[tuple[str, str]]:
    """(importer, imported) between spm_pin modules, packages included (code held in a
    package ``__init__`` counts). Left out: a package's re-exports, the top-level
    imports of a package ``__init__`` whose names are all in its ``__all__``."""
    table = modules()
    edges: set[tuple[str, str]] = set()
    for module, path in table.items():
        package = is_package(module, table)
        tree = ast.parse(path.read_text(encoding="utf-8"))
        exported = _public(tree) if package else set()
        for node in _imports(tree):
            names = [alias.asname or alias.name for alias in node.names]
            if package and node in tree.body and names and set(names) <= exported:
                continue  # a re-export
            if isinstance(node, ast.Import):
                targets = [_resolve(alias.name, None, table) for alias in node.names]
            else:
                source = _absolute(module, node, package)
                targets = [_resolve(source, alias.name, table) for alias in node.names]
            for target in targets:
                if target is not None and target != module and target != PACKAGE:
                    edges.add((module, target))
    return edges


def layer(module: str) -> int:
    part = module.split(".")[1] if "." in module else module
    return LAYERS[part]


# --------------------------------------------------------------------- analysis
def circles(edges: set[tuple[str, str]]) -> set[tuple[str, str]]:
    """Pairs of modules (sorted) that lie on one import circle together, reduced to the
    edges of each strongly connected component's circles."""
    graph: dict[str, set[str]] = {}
    for a, b in edges:
        graph.setdefault(a, set()).add(b)
        graph.setdefault(b, set())

    def reachable(start: str) -> set[str]:
        seen, stack = set(), [start]
        while stack:
            for nxt in graph[stack.pop()]:
                if nxt not in seen:
                    seen.add(nxt)
                    stack.append(nxt)
        return seen

    reach = {node: reachable(node) for node in graph}
    return {(min(a, b), max(a, b)) for a, b in edges if a in reach[b]}  # a -> b and b reaches a


def upward(edges: set[tuple[str, str]]) -> set[tuple[str, str]]:
    return {(a, b) for a, b in edges if layer(b) > layer(a)}


def long_modules() -> set[str]:
    return {
        name
        for name, path in modules().items()
        if len(path.read_text(encoding="utf-8").splitlines()) > MAX_LINES
    }


# ------------------------------------------------------------------------ tests
def test_every_part_has_a_layer() -> None:
    parts = {name.split(".")[1] for name in modules() if "." in name}
    assert parts <= set(LAYERS), f"give these parts a layer: {sorted(parts - set(LAYERS))}"


def test_the_reader_sees_known_imports() -> None:
    """The reader is not blind: it finds imports of each kind that are known to exist."""
    edges = import_edges()
    assert ("spm_pin.kinematics.fk", "spm_pin.kinematics._common") in edges  # relative
    assert ("spm_pin.model.robot", "spm_pin.kinematics.fk") in edges  # via a package
    assert ("spm_pin.collision.checker", "spm_pin.model.robot") in edges
    assert ("spm_pin.collision.pieces", "spm_pin.collision._shapes") in edges  # sibling
    # a function-level import (the study's robot, with its collision checker)
    assert ("spm_pin.study.context", "spm_pin.collision.checker") in edges
    # code in a package __init__ counts (the spm parser is built in cli/__init__.py)
    assert ("spm_pin.cli", "spm_pin.cli.kinematics") in edges
    assert not any(a == "spm_pin" for a, _ in edges)  # the top package only re-exports
    # a package __init__ that only re-exports imports nothing
    assert not any(a == "spm_pin.collision" for a, _ in edges)
    # imports inside functions count; under `if TYPE_CHECKING:` they do not
    source = (
        "import typing\n"
        "if typing.TYPE_CHECKING:\n    from .a import A\nelse:\n    import b\n"
        "def f():\n    from .c import C\n"
    )
    read = [
        node.module if isinstance(node, ast.ImportFrom) else node.names[0].name
        for node in _imports(ast.parse(source))
    ]
    assert sorted(str(x) for x in read) == ["b", "c", "typing"]


@pytest.mark.parametrize("rule", ["circles", "upward", "long"])
def test_house_rules(rule: str) -> None:
    edges = import_edges()
    found: set[object] = set(
        {"circles": circles, "upward": upward}[rule](edges) if rule != "long" else long_modules()
    )
    allowed = ALLOWED[rule]
    new = sorted(map(str, found - allowed))
    gone = sorted(map(str, allowed - found))
    assert not new, f"{rule}: new violations of the house rules: {new}"
    assert not gone, f"{rule}: fixed, so delete from ALLOWED[{rule!r}]: {gone}"


def test_nothing_imports_the_command_line() -> None:
    importers = {
        a
        for a, b in import_edges()
        if b.startswith("spm_pin.cli") and not a.startswith("spm_pin.cli")
    }
    pairs = [pair for pair in ALLOWED["upward"] if isinstance(pair, tuple)]
    allowed = {a for a, b in pairs if b.startswith("spm_pin.cli")}
    assert importers <= {"spm_pin.__main__", *allowed}, sorted(importers)


#: Import paths users may have written: they keep working as the house is rebuilt.
USER_PATHS = [
    ("spm_pin.collision", "CollisionChecker"),
    ("spm_pin.collision", "CollisionReport"),
    ("spm_pin.collision", "ConvexPiece"),
    ("spm_pin.collision", "convex_pieces"),
    ("spm_pin.collision", "check_input"),
    ("spm_pin.collision", "LINK_PAIRS"),
    ("spm_pin.collision", "ADJACENT_PAIRS"),
    ("spm_pin.closure", "ClosedLoop"),
    ("spm_pin.closure", "ProjectionResult"),
    ("spm_pin.model.robot", "SPMRobot"),
    ("spm_pin.model.robot", "build_robot"),
    ("spm_pin.kinematics", "forward_kinematics"),
    ("spm_pin.cli", "main"),
    ("spm_pin.cli", "fk_record"),
    ("spm_pin.cli", "fk_all_record"),
    ("spm_pin.demo", "run_demo"),
    ("spm_pin.demo", "DemoContext"),
    ("spm_pin.demo", "DEMO_SECTIONS"),
    ("spm_pin.study", "run_demo"),
    ("spm_pin.workspace", "workspace_map"),
    ("spm_pin.workspace", "WorkspaceMap"),
    ("spm_pin.workspace", "WorkspaceSettings"),
    ("spm_pin.workspace", "gaps_from_theta"),
    ("spm_pin.dynamics", "ClosedLoopDynamics"),
    ("spm_pin.dynamics", "Simulator"),
    ("spm_pin.dynamics", "ServoModel"),
    ("spm_pin.dynamics", "XM540_W150"),
    ("spm_pin.dynamics", "Trajectory"),
    ("spm_pin.dynamics", "forward_dynamics"),
    ("spm_pin.dynamics", "simulate_mujoco"),
    ("spm_pin.dynamics", "MUJOCO_SOLIMP"),
    ("spm_pin.closure", "PathResult"),
    ("spm_pin.closure", "FrameTargetResult"),
    ("spm_pin.closure", "EUCLIDEAN_JOINTS"),
    ("spm_pin.closure", "DEFAULT_TOL"),
    ("spm_pin.closure", "CLOSED_TOL"),
    ("spm_pin.collision", "build_robot"),
    ("spm_pin.collision", "checker_of"),
    ("spm_pin.collision", "LinkPair"),
    ("spm_pin.calibration", "calibrate"),
    ("spm_pin.calibration", "Readings"),
    ("spm_pin.calibration", "CalibrationResult"),
    ("spm_pin.calibration", "plan_poses"),
    ("spm_pin.calibration", "synthetic_readings"),
]


@pytest.mark.parametrize(("module", "name"), USER_PATHS, ids=[".".join(p) for p in USER_PATHS])
def test_old_import_paths_still_work(module: str, name: str) -> None:
    import importlib

    assert hasattr(importlib.import_module(module), name)


def test_every_public_name_still_imports() -> None:
    import importlib

    import spm_pin

    missing = [name for name in spm_pin.__all__ if not hasattr(spm_pin, name)]
    assert not missing, missing
    # and every name each package promises in its __all__
    for package in (
        "collision",
        "closure",
        "dynamics",
        "workspace",
        "calibration",
        "study",
        "demo",
        "cli",
    ):
        module = importlib.import_module(f"spm_pin.{package}")
        missing = [name for name in module.__all__ if not hasattr(module, name)]
        assert not missing, (package, missing)
