"""Write output files without destroying anything: checked paths, temporary file, atomic rename.

Every file tactile-torch writes (data and model files, ONNX bundles, CSV logs, the labels of
``predict``) goes through :func:`write_atomic`, which refuses in one line (``ValueError``) to write

- onto a directory, a device, a FIFO or a socket (``--out /dev/null`` would otherwise replace the
  device node with a regular file when run as root);
- through a symbolic link (the rename would replace the link, not write where it points: name the
  target itself);
- onto one of the command's inputs (``export --model m.npz --out m.npz``,
  ``predict --data d.npz --out d.npz``), compared by device and inode, so hard links and other
  spellings of the same path are caught too;

and otherwise writes a temporary file in the same directory and renames it over ``path``, so that a
crash, a full disk or an interrupted run never leaves a truncated file under the final name. A place
where nothing can be created (a read-only file system, a directory without write permission) is refused
first, naming the output; :func:`check_output_dir` checks an output directory the same way. NumPy and
the standard library only (runs on the robot).

Examples
--------
>>> import os, tempfile
>>> path = os.path.join(tempfile.mkdtemp(), "labels.txt")
>>> write_atomic(path, lambda f: f.write(b"cork\\n")).read_text()
'cork\\n'
"""

from __future__ import annotations

import os
import stat
import tempfile
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import BinaryIO

PathLike = str | os.PathLike


def _same_file(a: os.stat_result, b: os.stat_result) -> bool:
    return (a.st_dev, a.st_ino) == (b.st_dev, b.st_ino)


def check_output_path(path: PathLike, *, inputs: Iterable[PathLike] = (), what: str = "output") -> Path:
    """Return ``path`` as a :class:`~pathlib.Path` if a file may be written there, else raise ``ValueError``.

    ``path`` may not exist yet (its parent directories are created by :func:`write_atomic`). An
    existing ``path`` must be a regular file that is none of ``inputs`` (the files the command reads).

    Parameters
    ----------
    path : str or PathLike
        Where the output will be written.
    inputs : iterable of str or PathLike
        Files the command reads; missing ones are ignored.
    what : str
        How messages name the output (e.g. ``"--out"``).
    """
    path = Path(path)
    try:
        here = path.lstat()
    except FileNotFoundError:
        _check_writable(path.parent, path, what)
        return path
    except OSError as err:  # e.g. a path through a regular file: ENOTDIR
        raise ValueError(f"{what} {path}: cannot write there ({err.strerror})") from None
    _check_writable(path.parent, path, what)
    if stat.S_ISLNK(here.st_mode):
        raise ValueError(
            f"{what} {path} is a symbolic link (to {os.readlink(path)}); refusing to write through it: "
            "name the file itself"
        )
    if stat.S_ISDIR(here.st_mode):
        raise ValueError(f"{what} {path} is a directory, expected a file name")
    if not stat.S_ISREG(here.st_mode):
        kind = (
            "a device"
            if stat.S_ISCHR(here.st_mode) or stat.S_ISBLK(here.st_mode)
            else "a FIFO"
            if stat.S_ISFIFO(here.st_mode)
            else "a socket"
            if stat.S_ISSOCK(here.st_mode)
            else "not a regular file"
        )
        raise ValueError(f"{what} {path} is {kind}; refusing to replace it with a file")
    for source in inputs:
        try:
            theirs = os.stat(source)
        except OSError:
            continue
        if _same_file(here, theirs):
            raise ValueError(
                f"{what} {path} is the input file {source}; refusing to overwrite it: choose another name"
            )
    return path


def _check_writable(directory: Path, path: Path, what: str) -> None:
    """Raise ``ValueError`` naming ``what`` unless files can be created in ``directory`` (or, when it does
    not exist yet, in its nearest existing ancestor, where the missing directories would be made)."""
    existing = Path(os.path.abspath(directory))
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if not existing.is_dir():
        raise ValueError(f"{what} {path}: cannot write there ({existing} is not a directory)")
    if not os.access(existing, os.W_OK | os.X_OK):  # read-only file system or no permission
        raise ValueError(f"{what} {path}: cannot write there ({existing} is not writable)")
    try:  # what access() cannot see (root, special file systems): make and remove an empty directory
        os.rmdir(tempfile.mkdtemp(prefix=".tactile-torch-probe-", dir=existing))
    except OSError as err:
        raise ValueError(
            f"{what} {path}: cannot write there ({existing}: {err.strerror or type(err).__name__})"
        ) from None


def check_output_dir(path: PathLike, *, what: str = "output", replace: bool = False) -> Path:
    """Return ``path`` as a :class:`~pathlib.Path` if a directory of outputs may be written there, else
    raise ``ValueError`` naming ``what``: before any work, rather than after it, naming a temporary file.

    An existing ``path`` must be a directory. ``replace``: the outputs are written next to ``path`` and
    moved into place as a whole (``tactile-torch tradeoff``), so its parent must be writable; otherwise
    they are written into ``path`` (or the nearest existing ancestor, where it would be made).

    Examples
    --------
    >>> import tempfile
    >>> check_output_dir(tempfile.mkdtemp() + "/runs/x", what="--out").name
    'x'
    """
    path = Path(path)
    try:
        here = path.stat()
    except FileNotFoundError:
        here = None
    except OSError as err:  # e.g. a path through a regular file: ENOTDIR
        raise ValueError(f"{what} {path}: cannot write there ({err.strerror})") from None
    if here is not None and not stat.S_ISDIR(here.st_mode):
        raise ValueError(f"{what} {path} exists and is not a directory; name a directory")
    _check_writable(path.parent if replace or here is None else path, path, what)
    return path


def write_atomic(
    path: PathLike,
    write: Callable[[BinaryIO], object],
    *,
    inputs: Iterable[PathLike] = (),
    what: str = "output",
    mode: int = 0o644,
) -> Path:
    """Write a file through ``write(f)`` (``f`` a binary file) to a temporary name, then rename it to ``path``.

    Checks ``path`` first (:func:`check_output_path`); creates missing parent directories. The file
    gets permissions ``mode`` (data and model files are meant to be shared). Returns ``path``.
    """
    inputs = list(inputs)
    path = check_output_path(path, inputs=inputs, what=what)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            write(f)
        os.chmod(tmp, mode)
        check_output_path(path, inputs=inputs, what=what)  # what appeared there while writing
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


__all__ = ["check_output_dir", "check_output_path", "write_atomic"]
