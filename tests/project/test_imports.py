"""The library's import graph: no cycle between modules, and no new arrow up the floors of CONTRIBUTING.md.

Read from the source, nothing imported: every line that starts an ``import`` or ``from ... import``
statement, wherever it stands (at the top, inside a function, under ``if TYPE_CHECKING:``), is parsed
with ``ast`` (a parenthesised import with its continuation lines). The linter keeps one statement per
line (ruff's E701, E702), so no import hides behind a ``:`` or ``;``; a line inside a string that reads
like an import counts too, which can only add an arrow, never hide one. Parsing the import lines
rather than whole modules keeps the check at a fraction of a second. Each statement is an arrow. ``from package import name`` points at the module
``package.name`` when there is one, else at ``package``. Lookups of a name at run time are not arrows:
a package ``__init__``'s lazy exports (``_exports.lazy_exports``) and a deprecated alias
(``_exports.moved_names``, the old module names its new home, which may import it).

- **Cycles**: no strongly connected component of more than one module.
- **Floors** ("The target layout" in CONTRIBUTING.md): each top-level package or module of the library
  has a target folder and a floor (:data:`FLOORS`; a new one must be placed there). An arrow between two
  target folders goes to a lower floor, or to floor 0's helpers. The arrows that still go up are
  :data:`UPWARD_ALLOWED`, each with the planned move that removes it: the list may only shrink (an arrow
  in it that no longer exists fails too, so that it is crossed off).
"""

from __future__ import annotations

import ast
import functools
import re
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
LIBRARY = ROOT / "tactile_torch"

# Current top-level package or module (below the library; "" is its __init__) -> (target folder, floor).
# Several current ones share a target folder when the plan moves them together: arrows inside one
# folder are free. Floor 7 is ordered: report < robustness < tradeoff < studies.
FLOORS = {
    "": ("base", 0),
    "_exports": ("base", 0),
    "_checks": ("base", 0),
    "_constraints": ("base", 0),
    "_parallel": ("base", 0),
    "robot": ("robot", 0),
    "data": ("data", 1),
    "image": ("image", 1),
    "signal": ("signal", 1),
    "metrics": ("ops", 1),
    "noise": ("ops", 1),
    "sensor_limits": ("ops", 1),
    "svm": ("svm", 2),
    "mixture": ("mixture", 2),
    "neural": ("neural", 2),
    "ood": ("ood", 2),
    "catalogue": ("catalogue", 3),
    "_onnx": ("export", 4),
    "classifier_inference": ("export", 4),
    "pipeline": ("export", 4),
    "engine": ("engine", 5),
    "model_selection": ("engine", 5),
    "training": ("workflows", 6),
    "clustering": ("workflows", 6),
    "clustering_model": ("workflows", 6),
    "default_bundles": ("workflows", 6),
    "report": ("report", 7.0),
    "robustness": ("robustness", 7.1),
    "tradeoff": ("tradeoff", 7.2),
    "studies": ("studies", 7.3),
    "cli": ("cli", 8),
    "warmup": ("cli", 8),
}

# Arrows up the floors that remain (2026-11-29), between current packages, with the move that removes
# each. Crossing one off (after the move) is required: the test fails on an arrow listed here that no
# longer exists, and on any arrow up not listed.
UPWARD_ALLOWED = {
    (
        "neural",
        "_onnx",
    ): "neural/export.py moves to the export package; neural/comparison.py (a workflow) to engine/",
    ("neural", "tradeoff"): "neural/front_end.py uses tradeoff/transformers.py (moves down to features/); "
    "neural/comparison.py uses tradeoff's export, int8, memory and selection (it moves up, to engine/)",
    ("ood", "_onnx"): "ood.py's ONNX graph moves to the export package",
    ("pipeline", "tradeoff"): "pipeline.py uses tradeoff/transformers.py (moves down to features/)",
    (
        "training",
        "tradeoff",
    ): "training.py uses tradeoff/transformers.py (moves to features/) and tradeoff/inputs.py's "
    "DEFAULT_FRAME_RATE_HZ (its folds are in engine/folds.py now)",
}


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


def upward_arrows(arrows: set[tuple[str, str]], floors: dict[str, tuple[str, float]]) -> set[tuple[str, str]]:
    """The arrows between two target folders that do not go down to a lower floor (floor 0 excepted)."""
    bad = set()
    for a, b in arrows:
        (folder_a, floor_a), (folder_b, floor_b) = floors[a], floors[b]
        if folder_a != folder_b and floor_b != 0 and floor_b >= floor_a:
            bad.add((a, b))
    return bad


@functools.cache
def _library_graph() -> dict[str, set[str]]:
    return import_graph(LIBRARY)


def test_no_import_cycle_between_modules():
    assert cycles(_library_graph()) == []


def test_every_package_has_a_floor():
    placed = {top_level(name) for name in modules(LIBRARY)}
    assert sorted(placed - set(FLOORS)) == [], "place it in FLOORS (and in CONTRIBUTING.md's target layout)"
    assert sorted(set(FLOORS) - placed) == [], "gone from the library: drop it from FLOORS"


def test_no_new_arrow_up_the_floors():
    up = upward_arrows(package_arrows(_library_graph()), FLOORS)
    assert sorted(up - set(UPWARD_ALLOWED)) == [], "a new arrow up the floors: import downwards only"
    assert sorted(set(UPWARD_ALLOWED) - up) == [], "gone: cross it off UPWARD_ALLOWED"


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
