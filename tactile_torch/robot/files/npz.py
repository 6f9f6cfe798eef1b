"""Bounded, pickle-free reading and atomic writing of ``.npz`` archives: data files and model files.

Every reader of the robot side checks what a file declares against one read bound
(:func:`max_read_bytes`: 1 GiB by default, ``$TACTILE_TORCH_MAX_READ_MB``, ``--max-read-mb``) before
it allocates: the sizes in a zip's member headers and the shape and dtype in each ``.npy`` header
(:func:`check_npz_size`), so a crafted archive (a zip bomb, a header declaring 10^12 samples) is
refused in one line. :func:`read_npz` never unpickles unless asked; :func:`write_npz` writes through
:func:`tactile_torch.robot.files.safe_write.write_atomic`. What the arrays of a data file mean is
:mod:`tactile_torch.robot.files.formats`'s business, those of a model file
:mod:`tactile_torch.robot.files.model_file`'s.

Examples
--------
>>> import numpy as np, tempfile, os
>>> path = os.path.join(tempfile.mkdtemp(), "a.npz")
>>> _ = write_npz(path, {"x": np.arange(3)})
>>> read_npz(path)["x"]
array([0, 1, 2])
"""

from __future__ import annotations

import os
import zipfile
import zlib
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ...exceptions import InputTypeError
from ...validation import check_count
from .safe_write import write_atomic

PathLike = str | os.PathLike
NPZ_MAGIC = b"PK"
NPY_MAGIC = b"\x93NUMPY"


def check_file(path: PathLike, what: str = "a file") -> Path:
    """Return ``path`` if it names a regular file, else raise one line saying what it is.

    ``FileNotFoundError`` when nothing is there; ``ValueError`` for a directory, a FIFO, a device or a
    socket (which a reader would block on or read without end), naming ``what`` was expected.
    """
    import stat

    path = Path(path)
    try:
        mode = path.stat().st_mode
    except FileNotFoundError:
        raise FileNotFoundError(f"{path}: no such file, expected {what}") from None
    if stat.S_ISDIR(mode):
        raise ValueError(f"{path}: is a directory, expected {what}")
    if not stat.S_ISREG(mode):
        kind = (
            "a FIFO"
            if stat.S_ISFIFO(mode)
            else "a device"
            if stat.S_ISCHR(mode) or stat.S_ISBLK(mode)
            else "not a regular file"
        )
        raise ValueError(f"{path}: is {kind}, expected {what}")
    return path


def _check_exists(path: Path) -> None:
    check_file(path)


# ------------------------------------------------------------------------------------ read limits
DEFAULT_MAX_READ_MB = 1024
"""Default bound (MiB) on what one data, model or bundle file may make the reader allocate."""
MAX_READ_ENV = "TACTILE_TORCH_MAX_READ_MB"
"""Environment variable that replaces :data:`DEFAULT_MAX_READ_MB` (``--max-read-mb`` sets it)."""
_MIB = 1 << 20


def max_read_bytes(max_bytes: int | None = None) -> int:
    """Return the read bound in bytes: ``max_bytes`` if given, else ``$TACTILE_TORCH_MAX_READ_MB`` MiB, else 1 GiB.

    Every reader of this module checks what a file declares (the sizes in a zip's member headers,
    the shape and dtype in each ``.npy`` header, a CSV's size) against this bound before reading, so
    a crafted file (a zip bomb, a header declaring 10^12 samples) is refused in one line instead of
    exhausting the memory of a robot's computer.
    """
    if max_bytes is None:
        text = os.environ.get(MAX_READ_ENV, "")
        try:
            mib = float(text) if text else float(DEFAULT_MAX_READ_MB)
        except ValueError:
            mib = float("nan")
        if not (mib > 0 and np.isfinite(mib)):
            raise ValueError(f"{MAX_READ_ENV} must be a number of MiB > 0, got {text!r}")
        return int(mib * _MIB)
    return check_count(max_bytes, "max_bytes", 1)


def _too_large(path: Path, what: str, size: int, limit: int) -> ValueError:
    return ValueError(
        f"{path}: {what} needs {size / _MIB:,.1f} MiB, more than the read limit of {limit / _MIB:,.0f} MiB "
        f"(raise it with {MAX_READ_ENV}=MB if the file is trusted)"
    )


def _npy_header(member, version: tuple[int, int]) -> tuple[tuple[int, ...], bool, np.dtype]:
    if version == (1, 0):
        return np.lib.format.read_array_header_1_0(member)
    if version == (2, 0):
        return np.lib.format.read_array_header_2_0(member)
    raise ValueError(f"unsupported .npy format version {version}")


def check_npz_size(path: PathLike, *, max_bytes: int | None = None, what: str = ".npz archive") -> int:
    """Check a ``.npz`` against the read bound without decompressing it; return the bytes its arrays need.

    Reads the zip's central directory (the declared uncompressed size of each member: ``zipfile``
    never inflates a member beyond it) and the header of each ``.npy`` member (shape and dtype,
    computed with Python integers: no overflow), and raises ``ValueError`` in one line when either
    total exceeds :func:`max_read_bytes`, or a member's shape needs more bytes than it holds.
    """
    path = Path(path)
    limit = max_read_bytes(max_bytes)
    name = ""
    try:
        with zipfile.ZipFile(path) as archive:
            members = archive.infolist()
            declared = sum(info.file_size for info in members)
            if declared > limit:
                raise _too_large(path, f"decompressing the {what}", declared, limit)
            needed = 0
            for info in members:
                name = info.filename
                with archive.open(info) as member:
                    try:
                        version = np.lib.format.read_magic(member)
                        shape, _, dtype = _npy_header(member, version)
                    except ValueError:
                        continue  # not a .npy member: read_npz names it
                if dtype.hasobject:
                    continue  # pickled: refused by read_npz unless allow_pickle
                size = dtype.itemsize
                for n in shape:
                    size *= int(n)
                if size > info.file_size:
                    raise ValueError(
                        f"{path}: {info.filename} declares shape {tuple(shape)} {dtype} ({size:,} bytes) but "
                        f"holds {info.file_size:,} bytes: a crafted or truncated {what}"
                    )
                needed += size
    # a damaged header: zipfile says NotImplementedError (an unknown compression method or version) or
    # RuntimeError (an encryption flag) where it means "not an archive I can read"
    except (zipfile.BadZipFile, zlib.error, EOFError, OSError, NotImplementedError, RuntimeError) as err:
        raise _corrupt(path, name, what, err) from None
    if needed > limit:
        raise _too_large(path, f"the {what}'s arrays", needed, limit)
    return needed


def read_npz(
    path: PathLike,
    *,
    allow_pickle: bool = False,
    what: str = ".npz archive",
    max_bytes: int | None = None,
) -> dict[str, np.ndarray]:
    """Return every array of a ``.npz`` file by name, or raise one ``ValueError`` naming the file.

    Empty, truncated or corrupt archives, files of another kind (a ``.npy``, an ONNX model, text) and
    pickled object arrays (unless ``allow_pickle``) are refused with a one-line reason; ``what``
    names the expected content in the messages (e.g. ``"tactile-torch model file"``). Before any
    array is read, the declared sizes are checked against ``max_bytes`` (default
    :func:`max_read_bytes`: 1 GiB, ``--max-read-mb``) by :func:`check_npz_size`.
    """
    path = Path(path)
    _check_exists(path)
    with path.open("rb") as f:
        head = f.read(8)
    if not head:
        raise ValueError(f"{path}: empty file (0 bytes), expected a {what}")
    if not head.startswith(NPZ_MAGIC):
        found = "a single .npy array" if head.startswith(NPY_MAGIC) else "not a zip archive"
        raise ValueError(f"{path}: expected a {what} (.npz), found {found}")
    check_npz_size(path, max_bytes=max_bytes, what=what)
    arrays: dict[str, np.ndarray] = {}
    member = ""
    try:
        with zipfile.ZipFile(path) as archive:
            for info in archive.infolist():
                member = info.filename
                key = member.removesuffix(".npy")
                with archive.open(info) as stream:
                    value = _read_member(stream, path, key, what, allow_pickle)
                    if stream.read(1):  # reading to the end checks the member's CRC-32
                        raise ValueError(f"{path}: {member} holds more bytes than its header declares")
                arrays[key] = value
    # a damaged header: zipfile says NotImplementedError (an unknown compression method or version) or
    # RuntimeError (an encryption flag) where it means "not an archive I can read"
    except (zipfile.BadZipFile, zlib.error, EOFError, OSError, NotImplementedError, RuntimeError) as err:
        raise _corrupt(path, member, what, err) from None
    return arrays


def _corrupt(path: Path, member: str, what: str, err: Exception) -> ValueError:
    """The one line for a damaged archive: the member whose data do not decompress or check, if known."""
    detail = " ".join(str(err).split())
    detail = detail if len(detail) <= 120 else detail[:117] + "..."
    if not member:
        return ValueError(f"{path}: truncated or corrupt {what} ({detail})")
    return ValueError(
        f"{path}: {member} is corrupt ({detail}): the {what} was damaged (a flipped bit, a cut copy); "
        "copy or write it again"
    )


def _read_member(stream, path: Path, key: str, what: str, allow_pickle: bool) -> np.ndarray:
    """One ``.npy`` member of an archive, as :func:`numpy.load` reads it (no pickle unless allowed)."""
    try:
        return np.lib.format.read_array(stream, allow_pickle=allow_pickle)
    except ValueError as err:
        if "allow_pickle" in str(err):
            raise ValueError(
                f"{path}: {key} is a pickled object array, which tactile-torch does not load by "
                "default (unpickling can run code); re-save it as plain arrays (docs/formats.md), or "
                "pass allow_pickle=True if you trust the file"
            ) from None
        if "magic" in str(err).lower():  # a zip member that is not a .npy array
            raise ValueError(
                f"{path}: expected a {what} (.npz), found a zip archive holding {key!r}"
            ) from None
        raise ValueError(f"{path}: unreadable {what} ({key}: {err})") from None


def write_npz(
    path: PathLike,
    arrays: dict[str, np.ndarray],
    *,
    compress: bool = True,
    inputs: Sequence[PathLike] = (),
) -> Path:
    """Write ``arrays`` to ``path`` exactly (no ``.npz`` appended), atomically; return the path.

    The archive is written to a temporary file next to ``path`` and renamed over it, so a crash or a
    full disk never leaves a truncated file under the final name; a directory, a device, a symbolic
    link or one of ``inputs`` (the files the caller read) at ``path`` is refused in one line
    (:func:`tactile_torch.robot.files.safe_write.write_atomic`). Object arrays are refused.
    """
    for key, value in arrays.items():
        if np.asarray(value).dtype == object:
            raise InputTypeError(f"{key} must be a plain (non-object) array to be written without pickle")
    save = np.savez_compressed if compress else np.savez
    return write_atomic(path, lambda f: save(f, **arrays), inputs=inputs)


__all__ = [
    "DEFAULT_MAX_READ_MB",
    "MAX_READ_ENV",
    "check_file",
    "check_npz_size",
    "max_read_bytes",
    "read_npz",
    "write_npz",
]
