"""``model_selection/`` is the one evaluation home: no module outside it builds scikit-learn's splitters or calls its
``cross_val_*``.

Read from the source, nothing imported: the import statements of every module of the library and of
the programs beside it (``train/``, ``export/``, ``bench/``), found as in ``test_imports.py`` (one
statement per line, a fraction of a second). A module that imports a splitter (``KFold``,
``StratifiedKFold``, ``GroupKFold``, ``StratifiedGroupKFold``, ``LeaveOneGroupOut``, any
``*ShuffleSplit``, ``TimeSeriesSplit`` ...), ``cross_val_score`` / ``cross_validate`` /
``cross_val_predict``, ``train_test_split``, or ``sklearn.model_selection`` itself (whose attributes it
could then use) makes folds outside the evaluation package: it must call
:mod:`tactile_torch.model_selection` (the folds; ``fold_predictions``, ``fold_scores``,
``cross_validate``) instead. The ones that still do are :data:`ALLOWED`, each with its reason: the list may only shrink (an
entry that no longer imports one fails too, so that it is crossed off).
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

from tests.project.test_imports import import_statements

ROOT = Path(__file__).resolve().parents[2]
SCANNED = ("tactile_torch", "train", "export", "bench")
HOME = "tactile_torch/model_selection/"

SPLITTERS = re.compile(
    r"^(?:\w*KFold|\w*ShuffleSplit|LeaveOne\w*Out|LeaveP\w*Out|TimeSeriesSplit|PredefinedSplit"
    r"|cross_val_score|cross_validate|cross_val_predict|train_test_split|\*)$"
)

# Module outside model_selection/ (path from the repository root) -> why it still makes its own folds.
ALLOWED = {
    "bench/bench_svm.py": "the benchmark times scikit-learn's own GridSearchCV against SVMGridSearchCV "
    "on the same StratifiedKFold: the reference it measures against, not an evaluation of the library",
}


def fold_imports(source: str) -> list[str]:
    """The splitters and ``cross_val_*`` names (or ``sklearn.model_selection`` itself) ``source`` imports."""
    found = []
    for node in import_statements(source):
        if isinstance(node, ast.ImportFrom) and not node.level and node.module:
            if node.module == "sklearn" or node.module.startswith("sklearn.model_selection"):
                for alias in node.names:
                    if node.module == "sklearn" and alias.name == "model_selection":
                        found.append("sklearn.model_selection")
                    elif node.module != "sklearn" and SPLITTERS.match(alias.name):
                        found.append(alias.name)
        elif isinstance(node, ast.Import):
            found += [a.name for a in node.names if a.name.startswith("sklearn.model_selection")]
    return found


def outside_model_selection(root: Path) -> dict[str, list[str]]:
    """Module (path from ``root``) outside ``model_selection/`` -> the fold makers it imports (modules that import none left out)."""
    hits = {}
    for top in SCANNED:
        for path in sorted((root / top).rglob("*.py")):
            rel = path.relative_to(root).as_posix()
            if rel.startswith(HOME) or "/.venv/" in f"/{rel}":
                continue
            names = fold_imports(path.read_text())
            if names:
                hits[rel] = names
    return hits


def test_no_module_outside_model_selection_makes_folds():
    hits = outside_model_selection(ROOT)
    new = {path: names for path, names in hits.items() if path not in ALLOWED}
    assert new == {}, (
        "make the folds in tactile_torch/model_selection (its splitters, fold_predictions, fold_scores)"
    )
    assert sorted(set(ALLOWED) - set(hits)) == [], "no longer makes folds: cross it off ALLOWED"


def test_the_check_finds_every_way_of_importing_a_splitter(tmp_path):
    (tmp_path / "tactile_torch" / "model_selection").mkdir(parents=True)
    (tmp_path / "tactile_torch" / "studies").mkdir()
    (tmp_path / "tactile_torch" / "model_selection" / "_split.py").write_text(
        "from sklearn.model_selection import StratifiedKFold\n"
    )
    (tmp_path / "tactile_torch" / "studies" / "a.py").write_text(
        "def f():\n    from sklearn.model_selection import (\n        GridSearchCV,\n        GroupShuffleSplit,\n"
        "        cross_val_predict,\n    )\n"
    )
    (tmp_path / "tactile_torch" / "b.py").write_text("import sklearn.model_selection as ms\n")
    (tmp_path / "tactile_torch" / "c.py").write_text("from sklearn import model_selection, svm\n")
    (tmp_path / "tactile_torch" / "d.py").write_text(
        "from sklearn.model_selection._split import TimeSeriesSplit, LeaveOneGroupOut\n"
    )
    (tmp_path / "tactile_torch" / "ok.py").write_text(
        "from sklearn.model_selection import GridSearchCV, ParameterGrid, check_cv\n"
        "from ..model_selection import cross_validate\n"
    )
    assert outside_model_selection(tmp_path) == {
        "tactile_torch/b.py": ["sklearn.model_selection"],
        "tactile_torch/c.py": ["sklearn.model_selection"],
        "tactile_torch/d.py": ["TimeSeriesSplit", "LeaveOneGroupOut"],
        "tactile_torch/studies/a.py": ["GroupShuffleSplit", "cross_val_predict"],
    }
