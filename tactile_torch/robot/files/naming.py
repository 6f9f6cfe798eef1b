"""Classes and sessions of recordings: the layout of a lab's files, index CSVs, and the checks on class names.

NumPy and the standard library only. :func:`recording_names` is the one rule every command's ``--data``
and the Python readers use to give each recording file its class and session:

* **Files in one folder**: the **naming rule** (:func:`class_and_session`): a file ``<class>_<n>``
  whose name ends in ``_`` and a number is recording ``n`` (the session) of class ``<class>``:
  ``felt_3.csv`` → class ``felt``, session ``3`` (``felt_03.csv`` too); any other name is a class and a
  session of its own (``glass.csv``).
* **Files in several folders** (a lab's tree): one level names the classes, the other the sessions.
  The names that repeat across the folders, and which level reads as dates or sessions
  (:func:`looks_like_sessions`: ``2026-11-02``, ``day3``, ``run_2``, ``monday``), decide: a folder
  per class ``<surface>/<date>.csv`` or a folder per session ``<day>/<surface>.csv``. Files all named
  ``<class>_<n>`` keep the naming rule (their folder is their session when it reads as one). A
  tree where both levels read as sessions, or neither does while the file names repeat across the
  folders, is refused in one line that names both readings.
* ``class_from`` / ``session_from`` (``--class-from``, ``--session-from``) say which level is which,
  and an **index CSV** (:func:`read_index`, ``--index``) gives each file's class and session.

The decision (:class:`RecordingNames`) says in one line what was read and why, with the classes and the
sessions (:meth:`RecordingNames.describe`): the commands print it before any long work.

Examples
--------
>>> class_and_session("logs/felt_3.csv"), class_and_session("glass.csv")
(('felt', '3'), ('glass', 'glass'))
>>> names = recording_names(["rec/cork/2026-11-02.csv", "rec/cork/2026-11-03.csv", "rec/felt/2026-11-02.csv"])
>>> names.layout, names.classes, names.sessions
('folder per class', ('cork', 'cork', 'felt'), ('2026-11-02', '2026-11-03', '2026-11-02'))
>>> recording_names(["day1/felt.csv", "day2/felt.csv", "day2/cork.csv"]).sessions
('day1', 'day2', 'day2')
"""

from __future__ import annotations

import csv
import os
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

PathLike = str | os.PathLike

INDEX_COLUMNS = ("file", "class")
"""Columns an index CSV must have (``session`` is optional)."""
_SUFFIXES = (".csv", ".db3", ".mcap", ".bag", ".npz")
"""File suffixes a recording's name leaves out (a bag directory keeps its whole name)."""


def class_and_session(path: PathLike) -> tuple[str, str]:
    """Return ``(class, session)`` of a recording from its file name (the naming rule above).

    >>> class_and_session("cork_12.csv"), class_and_session("run.bag"), class_and_session("a_b.mcap")
    (('cork', '12'), ('run', 'run'), ('a_b', 'a_b'))
    """
    stem = _stem(path)
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


CLASS_SOURCES = ("folder", "file")
"""Where ``class_from`` (``--class-from``) takes each file's class: its folder, or its file name."""
SESSION_SOURCES = ("folder", "file", "recording")
"""Where ``session_from`` (``--session-from``) takes each file's session: its folder, its file name, or
the file itself (``recording``: every file its own session)."""
FRAME_LABELS = "frame recordings labelled frame by frame"
"""The layout of frame recordings whose frames carry their classes: the files give their sessions only."""
LAYOUTS = ("file names", "folder per class", "folder per session", "index", "given", FRAME_LABELS)
"""How :func:`recording_names` told classes and sessions apart (:attr:`RecordingNames.layout`)."""

_SESSION_WORDS = (
    "day|d|session|sess|ses|s|run|r|trial|take|rec|recording|week|wk|w|part|block|visit|v|test|seq|"
    "sequence|exp|experiment|batch|shift|round|log|trace|subject|sub|t"
)
_SESSION_NAME = re.compile(
    r"\d{4}[-_.]?\d{2}[-_.]?\d{2}(?:[t_ .-].*)?"  # 2026-11-02, 20261102, 2026-11-02T10-30, 2026-11-02_am
    r"|\d{1,2}[-_.]\d{1,2}[-_.]\d{2,4}(?:[t_ .-].*)?"  # 02-11-2026, 2.11.26
    rf"|(?:{_SESSION_WORDS})[-_ ]?\d+[a-z]?"  # day1, session_03, run-2, s1, take12b
    r"|\d+(?:st|nd|rd|th)?"  # 3, 03, 2nd
    r"|(?:mon|tue|tues|wed|thu|thur|thurs|fri|sat|sun)(?:day)?(?:[-_ ]?\d+)?"  # monday, tue_2
    r"|(?:morning|afternoon|evening|night|am|pm)(?:[-_ ]?\d+)?"
    r"|(?:jan|feb|mar|apr|may|jun|jul|aug|sep|sept|oct|nov|dec)[a-z]*[-_ ]?\d{1,2}(?:[-_ ]\d{2,4})?",
    re.IGNORECASE,
)
_WORD_AND_NUMBER = re.compile(r"(.+?)[-_ ](\d+)")


def looks_like_sessions(names: Sequence[str]) -> bool:
    """Return whether every name reads as a session (a day, a run) rather than a surface.

    A name reads as a session when it is a date (``2026-11-02``, ``20261102``), a day, run, take or
    session number (``day1``, ``session_03``, ``run-2``, ``3``), a weekday or a time of day; and all
    the names do when they are one word and a number (``imu_00``, ``imu_02``: the word they share
    tells nothing apart). ``p120`` (a sandpaper's grit) and ``felt_1`` next to ``cork_1`` do not.

    >>> looks_like_sessions(["2026-11-02", "2026-11-03"]), looks_like_sessions(["day1", "day2"])
    (True, True)
    >>> looks_like_sessions(["imu_00", "imu_02"]), looks_like_sessions(["cork", "felt"]), looks_like_sessions(["p120"])
    (True, False, False)
    """
    names = [str(n) for n in names]
    if not names:
        return False
    if all(_SESSION_NAME.fullmatch(n) for n in names):
        return True
    words = {m[1].lower() if (m := _WORD_AND_NUMBER.fullmatch(n)) else None for n in names}
    return None not in words and len(words) == 1


def _stem(path: PathLike) -> str:
    p = Path(path)
    return p.stem if p.suffix.lower() in _SUFFIXES else p.name


def folder_names(paths: Sequence[PathLike]) -> list[str] | None:
    """Return each path's folder below the folders' common ancestor, or ``None`` when all lie in one folder.

    Two folders of one name below different parents stay two (``a/day1``, ``b/day1``).

    >>> folder_names(["logs/day1/felt.csv", "logs/day2/felt.csv"]), folder_names(["felt.csv", "cork.csv"])
    (['day1', 'day2'], None)
    >>> folder_names(["a/day1/x.csv", "b/day1/x.csv"])
    ['a/day1', 'b/day1']
    """
    parents = [Path(os.path.abspath(p)).parent for p in paths]
    if len(set(parents)) < 2:
        return None
    root = Path(os.path.commonpath([str(p) for p in parents]))
    return [p.relative_to(root).as_posix() if p != root else (p.name or p.as_posix()) for p in parents]


def name_list(names: Sequence[str], limit: int = 8) -> str:
    """Return the distinct ``names`` in order, comma-separated: the first ``limit`` and how many more.

    >>> name_list(["b", "a", "b", "c"], limit=2)
    'b, a and 1 more'
    """
    names = list(dict.fromkeys(str(n) for n in names))
    shown = ", ".join(names[:limit])
    return shown + (f" and {len(names) - limit} more" if len(names) > limit else "")


@dataclass(frozen=True)
class RecordingNames:
    """Each recording file's class and session, and how they were told apart (:func:`recording_names`).

    Attributes
    ----------
    classes, sessions : tuple of str
        One per file, in the order given.
    layout : str
        One of :data:`LAYOUTS`: ``"file names"`` (the naming rule, ``felt_3.csv``), ``"folder per
        class"`` (``<class>/<session>.csv``), ``"folder per session"`` (``<session>/<class>.csv``),
        ``"index"`` (an index CSV) or ``"given"`` (``class_names=``, ``sessions=``,
        ``class_from=``/``session_from=``).
    reason : str
        Why, in words, with an example file.
    other_way : str
        The argument that reads the files the other way (``"class_from='file'"``), or ``""``.
    """

    classes: tuple[str, ...]
    sessions: tuple[str, ...]
    layout: str
    reason: str
    other_way: str = ""

    def describe(self) -> str:
        """Return one line: the layout and why, the classes and the sessions (what a command prints first).

        >>> RecordingNames(("cork", "felt"), ("1", "1"), "file names", "one folder").describe()
        '2 files read as file names (one folder): 2 classes (cork, felt), 1 session (1)'
        """
        classes, sessions = sorted(set(self.classes)), sorted(set(self.sessions))
        n, c, s = len(self.classes), len(classes), len(sessions)
        these = "" if self.layout == FRAME_LABELS else f"{c} class{'es' * (c != 1)} ({name_list(classes)}), "
        line = (
            f"{n} file{'s' * (n != 1)} read as {self.layout} ({self.reason}): {these}"
            f"{s} session{'s' * (s != 1)} ({name_list(sessions)})"
        )
        return line + (f"; {self.other_way} reads them the other way" if self.other_way else "")


def recording_names(
    paths: Sequence[PathLike],
    *,
    class_names: Sequence[str] | None = None,
    sessions: Sequence[str] | None = None,
    index: PathLike | dict | None = None,
    class_from: str | None = None,
    session_from: str | None = None,
) -> RecordingNames:
    """Return each recording file's class and session: given, from an index CSV, or read from the tree.

    The one rule of every command's ``--data`` and of the Python readers. Without ``class_names``,
    ``index``, ``class_from`` or ``session_from``, the tree decides (the module notes):

    * files in one folder: the naming rule (``felt_3.csv``: class ``felt``, session ``3``);
    * files in several folders: the names that repeat across the folders, and which of the two levels
      reads as dates or sessions (:func:`looks_like_sessions`), say which level names the classes:
      ``<class>/<date>.csv`` is a folder per class, ``<day>/<class>.csv`` a folder per session; files
      all named ``<class>_<n>`` keep the naming rule (their folder is the session when it reads as one);
      folders whose file names never repeat are a folder per class (unless each holds one file: the file
      names then give the classes). A tree where both levels read as sessions, or neither does while the
      names repeat, is refused with the fix.

    ``class_from`` (``"folder"`` or ``"file"``) and ``session_from`` (``"folder"``, ``"file"`` or
    ``"recording"``: every file its own session) override the tree; the one not given follows (the
    other level). ``class_names`` / ``sessions`` give them one per file.

    Raises
    ------
    ValueError
        One line: an ambiguous tree (naming both fixes), an override that cannot hold (a folder for
        files in one folder, class and session from one folder), a file missing from the index, or
        ``class_names``/``sessions`` not one per file.
    """
    paths = list(paths)
    for name, value, allowed in (
        ("class_from", class_from, CLASS_SOURCES),
        ("session_from", session_from, SESSION_SOURCES),
    ):
        if value is not None and value not in allowed:
            raise ValueError(f"{name} must be one of {allowed}, got {value!r}")
    if index is not None:
        if class_from is not None or session_from is not None:
            raise ValueError(
                "index= gives every file's class and session; class_from= and session_from= apply without it"
            )
        names = _from_index(paths, index)
    elif class_from is not None or session_from is not None:
        names = _as_told(paths, folder_names(paths), class_from, session_from)
    elif class_names is not None and sessions is not None:
        names = RecordingNames((), (), "given", "class_names= and sessions=")
    else:
        names = _from_tree(paths, folder_names(paths))
    classes = names.classes if class_names is None else tuple(str(c) for c in class_names)
    session = names.sessions if sessions is None else tuple(str(s) for s in sessions)
    for name, given in (("class_names", classes), ("sessions", session)):
        if len(given) != len(paths):
            raise ValueError(f"{name} must give one entry per file ({len(paths)}), got {len(given)}")
    if class_names is None and sessions is None:
        return names
    return RecordingNames(
        classes, session, "given", "class_names= and sessions=" if sessions is not None else "class_names="
    )


def _from_index(paths: list, index: PathLike | dict) -> RecordingNames:
    table = index if isinstance(index, dict) else read_index(index)
    absent = [str(p) for p in paths if str(Path(p).resolve()) not in table]
    if absent:
        where = index if not isinstance(index, dict) else "the index"
        raise ValueError(f"{where}: lists no class for {absent[0]} ({len(absent)} file(s) not in the index)")
    rule = [table[str(Path(p).resolve())] for p in paths]
    where = "the index" if isinstance(index, dict) else f"the index {index}"
    return RecordingNames(
        tuple(c for c, _ in rule), tuple(s for _, s in rule), "index", f"classes and sessions from {where}"
    )


def _example(path: PathLike, folder: str, class_from: str) -> str:
    """``"cork/2026-11-02.csv: class cork, session 2026-11-02"``: one file read with its class from ``class_from``."""
    klass, session = (folder, _stem(path)) if class_from == "folder" else (class_and_session(path)[0], folder)
    return f"{folder}/{Path(path).name}: class {klass}, session {session}"


def _ambiguous(paths: list, folders: list[str], why: str) -> ValueError:
    root = os.path.commonpath([os.path.dirname(os.path.normpath(str(p))) or "." for p in paths]) or "."
    return ValueError(
        f"{root}: cannot tell the classes from the sessions: {why}; say where the classes are: "
        f"class_from='folder' ({_example(paths[0], folders[0], 'folder')}) or class_from='file' "
        f"({_example(paths[0], folders[0], 'file')}), or give an index CSV (index=, columns file,class,session)"
    )


def _repeats(named: list[tuple[str, str]], folders: list[str]) -> bool:
    """Whether some file name (its class part: ``felt`` of ``felt_3``) lies in two folders."""
    seen: dict[str, str] = {}
    return any(
        seen.setdefault(klass, folder) != folder for (klass, _), folder in zip(named, folders, strict=True)
    )


def _from_tree(paths: list, folders: list[str] | None) -> RecordingNames:
    """The classes and sessions the tree of ``paths`` says (:func:`recording_names`' notes)."""
    named = [class_and_session(p) for p in paths]
    if folders is None:
        return RecordingNames(
            tuple(c for c, _ in named),
            tuple(s for _, s in named),
            "file names",
            "one folder: felt_3.csv is class felt, session 3; glass.csv a class and session of its own",
        )
    stems = [_stem(p) for p in paths]
    leaves = sorted({f.rsplit("/", 1)[-1] for f in folders})
    folder_sessions, file_sessions = looks_like_sessions(leaves), looks_like_sessions(sorted(set(stems)))
    numbered = all(c != s for c, s in named) and len({c for c, _ in named}) > 1
    if numbered and not folder_sessions:
        return RecordingNames(
            tuple(c for c, _ in named),
            tuple(s for _, s in named),
            "file names",
            "every file is named <class>_<n>: felt_3.csv is class felt, session 3",
        )
    by_folder = f"the folder names ({name_list(leaves, 3)})"
    by_file = f"the file names ({name_list(sorted(set(stems)), 3)})"
    if file_sessions and folder_sessions:
        raise _ambiguous(paths, folders, f"{by_folder} and {by_file} both look like dates or sessions")
    grouped = len(set(folders)) < len(folders)  # some folder holds several files
    if not (file_sessions or folder_sessions or grouped):  # a file per folder: the folders group nothing
        return RecordingNames(
            tuple(c for c, _ in named),
            tuple(s if c != s else f for (c, s), f in zip(named, folders, strict=True)),
            "file names",
            "each folder holds one file, so the file names give the classes (felt_3.csv: class felt, "
            "session 3; glass.csv: its folder is its session)",
            "class_from='folder'",
        )
    if file_sessions or not (folder_sessions or _repeats(named, folders)):
        why = (
            f"{by_file} look like dates or sessions, {by_folder} do not"
            if file_sessions
            else "no file name repeats across the folders: each holds one class's recordings"
        )
        return RecordingNames(
            tuple(folders),
            tuple(stems),
            "folder per class",
            f"{why}; {_example(paths[0], folders[0], 'folder')}",
            "class_from='file'",
        )
    if folder_sessions:
        return RecordingNames(
            tuple(c for c, _ in named),
            tuple(folders),
            "folder per session",
            f"{by_folder} look like dates or sessions, {by_file} do not; {_example(paths[0], folders[0], 'file')}",
            "class_from='folder'",
        )
    raise _ambiguous(
        paths,
        folders,
        f"{by_file} repeat across the folders ({name_list(leaves, 3)}) and neither looks like dates or sessions",
    )


def _as_told(
    paths: list, folders: list[str] | None, class_from: str | None, session_from: str | None
) -> RecordingNames:
    """The classes and sessions ``class_from`` / ``session_from`` say; the one not given takes the other level."""
    if class_from is None:
        class_from = {"folder": "file", "file": "folder"}.get(session_from)
        if class_from is None:  # session_from="recording": the classes as the tree has them
            class_from = "folder" if _from_tree(paths, folders).layout == "folder per class" else "file"
    if session_from is None:
        session_from = "file" if class_from == "folder" or folders is None else "folder"
    if folders is None and "folder" in (class_from, session_from):
        which = "class_from" if class_from == "folder" else "session_from"
        where = os.path.dirname(os.path.normpath(str(paths[0]))) or "."
        raise ValueError(
            f"{which}='folder': the files all lie in one folder ({where}), which would be one "
            f"{'class' if which == 'class_from' else 'session'}; give files in several folders, or "
            f"{which}='file'"
        )
    if class_from == session_from == "folder":
        raise ValueError(
            "class_from and session_from cannot both be 'folder': every class would be one session"
        )
    named = [class_and_session(p) for p in paths]
    classes = folders if class_from == "folder" else [c for c, _ in named]
    if session_from == "folder":
        session = folders
    elif session_from == "recording":
        root = os.path.commonpath([os.path.dirname(os.path.abspath(p)) for p in paths])
        session = [Path(os.path.relpath(os.path.abspath(p), root)).with_suffix("").as_posix() for p in paths]
    else:  # the file name: its number when the name gives the class too (felt_3), else the whole name
        session = [s for _, s in named] if class_from == "file" else [_stem(p) for p in paths]
    other = "" if folders is None else f"class_from='{'file' if class_from == 'folder' else 'folder'}'"
    return RecordingNames(
        tuple(classes),
        tuple(session),
        "folder per class"
        if class_from == "folder"
        else "folder per session"
        if session_from == "folder"
        else "file names",
        f"as told: class_from='{class_from}', session_from='{session_from}'",
        other,
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
    "CLASS_SOURCES",
    "FRAME_LABELS",
    "INDEX_COLUMNS",
    "LAYOUTS",
    "SESSION_SOURCES",
    "RecordingNames",
    "check_class_names",
    "class_and_session",
    "csv_class_name",
    "folder_names",
    "looks_like_sessions",
    "name_list",
    "read_index",
    "recording_names",
    "slug",
]
