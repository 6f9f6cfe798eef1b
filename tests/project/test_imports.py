"""The library's import graph: no cycle between modules, no circle between packages, and every arrow down the
floors of CONTRIBUTING.md.

Read from the source, nothing imported: every line that starts an ``import`` or ``from ... import``
statement, wherever it stands (at the top, inside a function, under ``if TYPE_CHECKING:``), is parsed
with ``ast`` (a parenthesised import with its continuation lines). The linter keeps one statement per
line (ruff's E701, E702), so no import hides behind a ``:`` or ``;``; a line inside a string that reads
like an import counts too, which can only add an arrow, never hide one. Parsing the import lines
rather than whole modules keeps the check at a fraction of a second. Each statement is an arrow. ``from package import name`` points at the module
``package.name`` when there is one, else at ``package``. Lookups of a name at run time are not arrows:
a package ``__init__``'s lazy exports (``_exports.lazy_exports``).

- **Cycles**: no strongly connected component of more than one module.
- **Circles between packages**: no strongly connected component of more than one top-level package or
  module of the library (``{engine, model_selection}`` was one: each imported a module of the other,
  with no cycle between the modules themselves).
- **Floors** ("The layout" in CONTRIBUTING.md): each top-level package or module of the library has a
  folder and an integer floor (:data:`FLOORS`; a new one must be placed there). An arrow between two
  folders goes to a lower floor, or to floor 0's helpers (the folder ``base``). :data:`UPWARD_ALLOWED`,
  the arrows that would still go up, is empty and stays so.
"""

from __future__ import annotations

import ast
import functools
import re
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
LIBRARY = ROOT / "tactile_torch"

# Top-level package or module of the library ("" is its __init__) -> (folder, floor). Modules that share a
# folder here are free to import each other (the workflows are top-level modules, as scikit-learn keeps
# modules, but one concern); between folders an arrow goes down a floor, or to floor 0's helpers ("base").
FLOORS = {
    "": ("base", 0),
    "_exports": ("base", 0),
    "_parallel": ("base", 0),
    "exceptions": ("base", 0),
    "validation": ("base", 0),
    "robot": ("robot", 0),
    "data": ("data", 1),
    "image": ("image", 1),
    "signal": ("signal", 1),
    "metrics": ("metrics", 1),
    "noise": ("noise", 1),
    "features": ("features", 2),
    "svm": ("svm", 3),
    "mixture": ("mixture", 3),
    "neural": ("neural", 3),
    "ood": ("ood", 3),
    "neighbors": ("neighbors", 3),
    "catalogue": ("catalogue", 4),
    "export": ("export", 5),
    "model_selection": ("model_selection", 6),
    "training": ("workflows", 7),
    "clustering": ("workflows", 7),
    "clustering_model": ("workflows", 7),
    "default_bundles": ("workflows", 7),
    "robustness": ("robustness", 8),
    "tradeoff": ("tradeoff", 9),
    "studies": ("studies", 10),
    "cli": ("cli", 11),
    "warmup": ("cli", 11),
}

# Arrows up the floors that are allowed: none (issue 40 removed the last five). A new one is a layout
# bug: move the code down, or the name to the lower package, instead of listing it here.
UPWARD_ALLOWED: dict[tuple[str, str], str] = {}


def modules(library: Path) -> dict[str, Path]:
    """Dotted name -> file of every module of the library (a package by its ``__init__.py``)."""
    found = {}
    for path in sorted(library.rglob("*.py")):
        parts = list(path.relative_to(library.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        found[".".join(parts)] = path
    return found


_IMPORT_LINE = re.compile(r"^[ \t]*(?:from[ \t]+\.*[\w.]*[ \t]+import\b|import[ \t]+\w)", re.MULTILINE)


def import_statements(text: str) -> list[ast.Import | ast.ImportFrom]:
    """The import statements of a module's source (see the module notes), parsed."""
    lines = text.splitlines()
    found = []
    for match in _IMPORT_LINE.finditer(text):
        k = text.count("\n", 0, match.start())
        statement = lines[k]
        while statement.count("(") > statement.count(")") or statement.rstrip().endswith("\\"):
            k += 1
            statement += "\n" + lines[k]
        found += ast.parse(textwrap.dedent(statement)).body
    return found


def import_graph(library: Path) -> dict[str, set[str]]:
    """Module -> the library's modules its import statements name (see the module notes)."""
    mods = modules(library)
    graph: dict[str, set[str]] = {name: set() for name in mods}
    for name, path in mods.items():
        package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
        for node in import_statements(path.read_text()):
            if isinstance(node, ast.ImportFrom):
                base = package[: len(package) - node.level + 1] if node.level else []
                target = ".".join(base + ([node.module] if node.module else []))
                for alias in node.names:
                    hit = next((t for t in (f"{target}.{alias.name}", target) if t in mods), None)
                    if hit and hit != name:
                        graph[name].add(hit)
            elif isinstance(node, ast.Import):
                for alias in node.names:
                    if alias.name in mods and alias.name != name:
                        graph[name].add(alias.name)
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan's algorithm, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found = []
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph.get(child, ())))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    found.append(sorted(component))
    return sorted(found)


def top_level(module: str) -> str:
    """The top-level package or module of a dotted name below the library (``""`` for its ``__init__``)."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else ""


def package_arrows(graph: dict[str, set[str]]) -> set[tuple[str, str]]:
    """The arrows between different top-level packages or modules."""
    return {
        (top_level(a), top_level(b))
        for a, targets in graph.items()
        for b in targets
        if top_level(a) != top_level(b)
    }


def package_graph(graph: dict[str, set[str]]) -> dict[str, set[str]]:
    """Top-level package or module -> the top-level packages or modules it imports (its own left out)."""
    packages: dict[str, set[str]] = {top_level(name): set() for name in graph}
    for a, b in package_arrows(graph):
        packages[a].add(b)
    return packages


def upward_arrows(arrows: set[tuple[str, str]], floors: dict[str, tuple[str, int]]) -> set[tuple[str, str]]:
    """The arrows between two folders that do not go down to a lower floor (floor 0's helpers excepted)."""
    bad = set()
    for a, b in arrows:
        (folder_a, floor_a), (folder_b, floor_b) = floors[a], floors[b]
        if folder_a != folder_b and folder_b != "base" and floor_b >= floor_a:
            bad.add((a, b))
    return bad


@functools.cache
def _library_graph() -> dict[str, set[str]]:
    return import_graph(LIBRARY)


def test_no_import_cycle_between_modules():
    assert cycles(_library_graph()) == []


def test_no_circle_between_packages():
    assert cycles(package_graph(_library_graph())) == []


def test_every_package_has_a_floor():
    placed = {top_level(name) for name in modules(LIBRARY)}
    assert sorted(placed - set(FLOORS)) == [], "place it in FLOORS (and in CONTRIBUTING.md's layout)"
    assert all(isinstance(floor, int) for _, floor in FLOORS.values()), "integer floors, no sub-floors"
    assert sorted(set(FLOORS) - placed) == [], "gone from the library: drop it from FLOORS"


def test_no_arrow_up_the_floors():
    assert UPWARD_ALLOWED == {}
    up = upward_arrows(package_arrows(_library_graph()), FLOORS)
    assert sorted(up) == [], "an arrow up the floors: import downwards only"


def test_the_checks_fail_on_violations(tmp_path):
    """A made-up cycle through a type-only import, and an arrow up, are both found."""
    library = tmp_path / "tactile_torch"
    (library / "svm").mkdir(parents=True)
    (library / "__init__.py").write_text("")
    (library / "svm" / "__init__.py").write_text("from .._exports import lazy_exports\n")
    (library / "_exports.py").write_text("")
    (library / "svm" / "tree.py").write_text(
        "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from .estimators import SVC\n"
    )
    (library / "svm" / "estimators.py").write_text(
        'def f():\n    """Doc."""\n    from . import (\n        tree,\n    )\n    from .. import catalogue\n'
    )
    (library / "catalogue.py").write_text("import tactile_torch.svm.tree\n")
    graph = import_graph(library)
    assert graph["tactile_torch.svm"] == {"tactile_torch._exports"}
    assert cycles(graph) == [
        ["tactile_torch.catalogue", "tactile_torch.svm.estimators", "tactile_torch.svm.tree"]
    ]
    floors = {"": ("base", 0), "_exports": ("base", 0), "svm": ("svm", 2), "catalogue": ("catalogue", 3)}
    assert upward_arrows(package_arrows(graph), floors) == {("svm", "catalogue")}
    assert cycles(package_graph(graph)) == [["catalogue", "svm"]]


def test_a_circle_between_packages_without_a_module_cycle_is_found(tmp_path):
    """{engine, model_selection} as it was: engine.tuning imports model_selection, which imports
    engine.folds: no module cycle, but a circle between the packages. And floor 0's helpers may not
    import the robot package (same floor, another folder), while the robot may import them."""
    library = tmp_path / "tactile_torch"
    (library / "engine").mkdir(parents=True)
    (library / "robot").mkdir()
    for path in ("__init__.py", "engine/__init__.py", "robot/__init__.py", "robot/runtime.py"):
        (library / path).write_text("")
    (library / "engine" / "folds.py").write_text("")
    (library / "engine" / "tuning.py").write_text("from ..model_selection import search\n")
    (library / "model_selection.py").write_text("from .engine.folds import split\n")
    (library / "validation.py").write_text("from .robot import runtime\n")
    (library / "robot" / "checks.py").write_text("from .. import _exports\n")
    (library / "_exports.py").write_text("")
    graph = import_graph(library)
    assert cycles(graph) == []
    assert cycles(package_graph(graph)) == [["engine", "model_selection"]]
    floors = {
        "": ("base", 0),
        "_exports": ("base", 0),
        "validation": ("base", 0),
        "robot": ("robot", 0),
        "engine": ("engine", 6),
        "model_selection": ("engine", 6),
    }
    assert upward_arrows(package_arrows(graph), floors) == {("validation", "robot")}
