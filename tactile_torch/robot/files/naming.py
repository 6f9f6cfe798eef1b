"""Classes and sessions of recordings: the naming rule, index CSVs, and the checks on class names (NumPy only).

**Naming rule** (:func:`class_and_session`, :func:`names_for`): a file ``<class>_<n>.<ext>`` whose
name ends in ``_`` and a number is recording ``n`` (the session) of class ``<class>``: ``felt_3.csv``
→ class ``felt``, session ``3`` (``felt_03.csv`` too). Any other name is a class of its own:
``glass.csv`` → class ``glass``; its session is its folder when the files given together lie in
several folders (``day2/glass.csv`` → session ``day2``, :func:`folder_sessions`), else the file
itself (session ``glass``). An index CSV (:func:`read_index`) overrides the rule.

Examples
--------
>>> class_and_session("logs/felt_3.csv"), class_and_session("glass.csv")
(('felt', '3'), ('glass', 'glass'))
>>> names_for(["day1/felt.csv", "day2/felt.csv", "day2/cork_7.csv"])
(['felt', 'felt', 'cork'], ['day1', 'day2', '7'])
"""

from __future__ import annotations

import csv
import os
from collections.abc import Sequence
from pathlib import Path

PathLike = str | os.PathLike

INDEX_COLUMNS = ("file", "class")
"""Columns an index CSV must have (``session`` is optional)."""


def class_and_session(path: PathLike) -> tuple[str, str]:
    """Return ``(class, session)`` of a recording from its file name (the naming rule above).

    >>> class_and_session("cork_12.csv"), class_and_session("run.bag"), class_and_session("a_b.mcap")
    (('cork', '12'), ('run', 'run'), ('a_b', 'a_b'))
    """
    stem = (
        Path(path).stem if Path(path).suffix.lower() in (".csv", ".db3", ".mcap", ".bag") else Path(path).name
    )
    base, _, tail = stem.rpartition("_")
    if base and tail.isdigit():
        return base, str(int(tail))  # felt_03 and cork_3 are both session 3
    return stem, stem


def read_index(path: PathLike) -> dict[str, tuple[str, str]]:
    """Return ``{file: (class, session)}`` from an index CSV with columns ``file,class[,session]``.

    ``file`` is a path relative to the index's directory (or absolute); a missing ``session``
    makes each file its own session. Keys are the resolved paths as strings.

    Raises
    ------
    ValueError
        One line naming the index file: a missing column, an empty class, a file listed twice.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such index file")
    with path.open(newline="") as f:
        reader = csv.DictReader(f)
        header = [h.strip().lower() for h in (reader.fieldnames or [])]
        missing = [c for c in INDEX_COLUMNS if c not in header]
        if missing:
            raise ValueError(
                f"{path}: an index CSV needs the columns file,class[,session], missing {missing} "
                f"(header: {header})"
            )
        reader.fieldnames = header
        index: dict[str, tuple[str, str]] = {}
        for row_number, row in enumerate(reader, start=2):
            name, label = (row.get("file") or "").strip(), (row.get("class") or "").strip()
            if not name or not label:
                raise ValueError(f"{path}: row {row_number} must give a file and a class, got {dict(row)}")
            key = str((path.parent / name).resolve())
            if key in index:
                raise ValueError(f"{path}: row {row_number} lists {name!r} a second time")
            index[key] = (label, (row.get("session") or "").strip() or Path(name).stem)
    if not index:
        raise ValueError(f"{path}: the index lists no file")
    return index


def folder_sessions(paths: Sequence[PathLike]) -> list[str] | None:
    """Return each path's folder as its session when the paths lie in more than one folder, else ``None``.

    The folder is named by its path below the folders' common ancestor (``day2`` for
    ``logs/day1/felt.csv`` next to ``logs/day2/felt.csv``; ``a/day1`` and ``b/day1`` for files in
    two folders both called ``day1``), so that two folders never give one session.

    >>> folder_sessions(["logs/day1/felt.csv", "logs/day2/felt.csv"]), folder_sessions(["felt.csv", "cork.csv"])
    (['day1', 'day2'], None)
    """
    parents = [Path(os.path.abspath(p)).parent for p in paths]
    if len(set(parents)) < 2:
        return None
    root = Path(os.path.commonpath([str(p) for p in parents]))
    return [p.relative_to(root).as_posix() if p != root else (p.name or p.as_posix()) for p in parents]


def names_for(
    paths: Sequence[PathLike],
    *,
    class_names: Sequence[str] | None = None,
    sessions: Sequence[str] | None = None,
    index: PathLike | dict | None = None,
) -> tuple[list[str], list[str]]:
    """Return each path's class and session: given explicitly, from an index CSV, or the naming rule.

    The naming rule (:func:`class_and_session`) gives the class; the session is the number at the
    end of the name (``felt_3.csv``: session ``3``), else the file's folder when the files lie in
    several folders (``day2/felt.csv``: session ``day2``, :func:`folder_sessions`), else the file
    itself (``glass.csv``: session ``glass``).

    Raises
    ------
    ValueError
        When ``class_names``/``sessions`` do not give one entry per file, or a file is not in the index.
    """
    if index is not None:
        table = index if isinstance(index, dict) else read_index(index)
        absent = [str(p) for p in paths if str(Path(p).resolve()) not in table]
        if absent:
            where = index if not isinstance(index, dict) else "the index"
            raise ValueError(
                f"{where}: lists no class for {absent[0]} ({len(absent)} file(s) not in the index)"
            )
        rule = [table[str(Path(p).resolve())] for p in paths]
    else:
        rule = [class_and_session(p) for p in paths]
        folders = folder_sessions(paths)
        if folders is not None:
            rule = [
                (c, folder if _unnumbered(p) else session)
                for p, (c, session), folder in zip(paths, rule, folders, strict=True)
            ]
    classes = [c for c, _ in rule] if class_names is None else [str(c) for c in class_names]
    session = [s for _, s in rule] if sessions is None else [str(s) for s in sessions]
    for name, given in (("class_names", classes), ("sessions", session)):
        if len(given) != len(paths):
            raise ValueError(f"{name} must give one entry per file ({len(paths)}), got {len(given)}")
    return classes, session


def _unnumbered(path: PathLike) -> bool:
    """Whether the naming rule finds no session number in the file's name (``glass.csv``)."""
    name, session = class_and_session(path)
    return name == session


def session_source(paths: Sequence[PathLike], *, index: PathLike | None = None) -> str:
    """Return where :func:`names_for` takes the files' sessions from, in words (for a command's report).

    >>> session_source(["day1/felt.csv", "day2/felt.csv"]), session_source(["felt_1.csv", "felt_2.csv"])
    ('their folders', 'the numbers in their names')
    """
    if index is not None:
        return f"the index {index}"
    numbered = [not _unnumbered(p) for p in paths]
    folders = folder_sessions(paths) is not None and not all(numbered)
    if all(numbered):
        return "the numbers in their names"
    if folders:
        return "the numbers in their names and their folders" if any(numbered) else "their folders"
    return (
        "the numbers in their names (the others are each their own)"
        if any(numbered)
        else "each file (its own)"
    )


def check_class_names(names: Sequence[str], where: str = "class_names") -> tuple[str, ...]:
    """Return ``names`` as a tuple if they can name classes, else raise ``ValueError`` starting with ``where``.

    A class name is printed in reports, one per line, and written into bundles: it must hold no
    control character (a newline would inject a line into a report), and no two may be equal (the
    labels would be ambiguous).
    """
    for i, name in enumerate(names):
        if any(ord(ch) < 32 or ord(ch) == 127 for ch in name):
            raise ValueError(
                f"{where} must hold no control characters (newline, tab, ...), got {name!r} at index {i}"
            )
    seen: dict[str, int] = {}
    for i, name in enumerate(names):
        if name in seen:
            raise ValueError(f"{where} must be distinct, got {name!r} at indices {seen[name]} and {i}")
        seen[name] = i
    return tuple(names)


def csv_class_name(path: PathLike) -> str:
    """Return the class a CSV log is named after (:func:`class_and_session`).

    >>> csv_class_name("logs/cork_12.csv"), csv_class_name("glass.csv")
    ('cork', 'glass')
    """
    return class_and_session(path)[0]


def slug(name: str) -> str:
    """Return ``name`` as a file stem: lower case, runs of other characters than letters and digits
    as one ``-``, none at the ends (``"SVM (RBF) + fused"`` -> ``"svm-rbf-fused"``).

    The one name-to-file rule of the exported ``.onnx`` files (trade-off candidates, deployed models,
    compared learned models). Letters and digits are Unicode's (``str.isalnum``); an empty result is
    possible (a name of punctuation only).

    >>> slug("SVM (RBF) + fused")
    'svm-rbf-fused'
    """
    return "-".join("".join(ch if ch.isalnum() else " " for ch in name.lower()).split())


__all__ = [
    "INDEX_COLUMNS",
    "check_class_names",
    "class_and_session",
    "csv_class_name",
    "folder_sessions",
    "names_for",
    "read_index",
    "session_source",
    "slug",
]
