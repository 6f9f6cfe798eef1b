"""The digest that seals an exported bundle: written by every exporter, checked on every load (no onnx).

A bundle's metadata property :data:`~tactile_torch.robot.contract.DIGEST_KEY` holds
``"sha256:<64 hex digits>"``, the SHA-256 of the file's bytes with that one property left out: the
graph, its weights, the opsets and every other metadata property (class names, window size,
thresholds) are covered, the digest is not (it cannot cover itself). The bytes are those of the file
as written, not of a re-serialisation, so the check needs no ``onnx`` package: a serialised
``ModelProto`` is a sequence of top-level protobuf fields (tag, then a value whose length the wire
type gives), and the digest's property is one top-level field 14 (``metadata_props``), which
:func:`seal` appends and :func:`check_digest` leaves out, wherever it stands. Walking the top level
reads a few dozen tags and skips the graph as one length-delimited field: the cost is the SHA-256 of
the file (about 1 GB/s).

Policy (docs/export.md, "Integrity"): a bundle whose digest does not match, that holds two digests,
or whose digest entry was damaged (its key or value is found in the file, but not as the digest
property) is refused with one line; so is a bundle without a digest (exported before digests
existed, by another tool, or with its digest stripped), whose integrity cannot be checked: export it
again, or :func:`seal_bundle` a copy you trust (``OnnxPipeline(..., allow_unsealed=True)`` loads one
with a warning, :class:`UnsealedBundleWarning`). The digest guards against damage, not against
someone who can write the file (they can seal what they changed).

Examples
--------
>>> sealed = seal(b"")                          # an empty ModelProto, sealed
>>> check_digest(sealed, "empty.onnx")
True
>>> check_digest(sealed[:-1] + b"0", "empty.onnx")  # doctest: +ELLIPSIS
Traceback (most recent call last):
...
ValueError: empty.onnx: the bundle's digest does not match its content (...): ...
"""

from __future__ import annotations

import contextlib
import hashlib
import re
from collections.abc import Iterator
from os import PathLike
from pathlib import Path

from .contract import DIGEST_KEY

DIGEST_PREFIX = "sha256:"
"""How the digest's value starts; 64 lower-case hexadecimal digits follow."""
_METADATA_FIELD = 14  # ModelProto.metadata_props (onnx.proto)
_DIGEST_VALUE = re.compile(rb"sha256:[0-9a-f]{64}")


class UnsealedBundleWarning(UserWarning):
    """A bundle without a digest was loaded: its integrity could not be checked."""


class _Corrupt(ValueError):
    """The bytes are not a protobuf message (a field runs past the end, an unknown wire type)."""


class NotProtobufError(ValueError):
    """The file is not a protobuf message, so not an ONNX file (``detail`` says where it breaks)."""

    def __init__(self, where: object, detail: str) -> None:
        self.detail = detail
        super().__init__(f"{where}: not an ONNX file: {detail}")


def _varint(data: bytes, pos: int) -> tuple[int, int]:
    value = shift = 0
    while True:
        if pos >= len(data) or shift > 63:
            raise _Corrupt(f"a number runs past byte {pos}")
        byte = data[pos]
        pos += 1
        value |= (byte & 0x7F) << shift
        if not byte & 0x80:
            return value, pos
        shift += 7


def _fields(data: bytes) -> list[tuple[int, int, int, int, int]]:
    """Return the top-level fields of a protobuf message: ``(number, wire type, start, payload start, end)``."""
    fields, pos = [], 0
    while pos < len(data):
        start = pos
        tag, pos = _varint(data, pos)
        number, wire = tag >> 3, tag & 7
        if wire == 0:
            _, end = _varint(data, pos)
        elif wire == 2:
            size, pos = _varint(data, pos)
            end = pos + size
        elif wire in (1, 5):
            end = pos + (8 if wire == 1 else 4)
        else:
            raise _Corrupt(f"wire type {wire} at byte {start}")
        if number == 0 or end > len(data):
            raise _Corrupt(f"field {number} at byte {start} runs past the end ({len(data)} bytes)")
        fields.append((number, wire, start, pos, end))
        pos = end
    return fields


def _digest_entries(data: bytes) -> list[tuple[int, int, bytes]]:
    """Return the digest properties of a serialised ``ModelProto``: ``(start, end, value)`` of each."""
    key = DIGEST_KEY.encode()
    found = []
    for number, wire, start, body, end in _fields(data):
        if number != _METADATA_FIELD or wire != 2:
            continue
        try:  # a StringStringEntryProto: key (1) and value (2), both strings
            parts = {n: data[body + b : body + e] for n, w, _, b, e in _fields(data[body:end]) if w == 2}
        except _Corrupt:
            continue
        if parts.get(1) == key:
            found.append((start, end, parts.get(2, b"")))
    return found


def _without(data: bytes, entries: list[tuple[int, int, bytes]]) -> list[memoryview]:
    """The byte ranges of ``data`` around ``entries`` (no copy)."""
    view, kept, pos = memoryview(data), [], 0
    for start, end, _ in entries:
        kept.append(view[pos:start])
        pos = end
    kept.append(view[pos:])
    return kept


def _sha256(parts: list[memoryview]) -> str:
    digest = hashlib.sha256()
    for part in parts:
        digest.update(part)
    return DIGEST_PREFIX + digest.hexdigest()


def _length_delimited(number: int, payload: bytes) -> bytes:
    out = bytearray()
    for value in (number << 3 | 2, len(payload)):
        while True:
            byte, value = value & 0x7F, value >> 7
            out.append(byte | (0x80 if value else 0))
            if not value:
                break
    return bytes(out) + payload


def seal(data: bytes) -> bytes:
    """Return a serialised ``ModelProto`` with its digest property (any previous one replaced)."""
    kept = _without(data, _digest_entries(data))
    entry = _length_delimited(1, DIGEST_KEY.encode()) + _length_delimited(2, _sha256(kept).encode())
    return b"".join(kept) + _length_delimited(_METADATA_FIELD, entry)


def check_digest(data: bytes, where: str | PathLike) -> bool:
    """Check a bundle's bytes against its digest; return ``True`` if it has one, ``False`` if not.

    Raises
    ------
    NotProtobufError
        A ``ValueError``: the bytes are not a protobuf message (one line naming ``where``).
    ValueError
        One line naming ``where``: the digest does not match
        (a bit flipped anywhere in the file but in the digest's own property, or the file was changed
        after export), the file holds two digests, or a digest's key or value is in the file but not as
        the digest property (its entry was damaged).
    """
    view = memoryview(data)
    return _verify(data, len(data), lambda start, end: (view[start:end],), where)


_CHUNK = 1 << 20


def check_file_digest(file, where: str | PathLike) -> bool:
    """Check the digest of the bundle in the open binary ``file`` (seekable); as :func:`check_digest`, reading it
    in chunks of 1 MiB rather than whole: what a bundle's check costs in memory does not grow with it.

    Returns ``True`` when the bundle has a digest (and it matches), ``False`` when it has none.
    """
    import mmap

    size = file.seek(0, 2)
    if size == 0:
        return check_digest(b"", where)
    buffer = bytearray(_CHUNK)

    def chunks(start: int, end: int):
        file.seek(start)
        while start < end:
            n = file.readinto(memoryview(buffer)[: min(_CHUNK, end - start)])
            if not n:
                return
            yield memoryview(buffer)[:n]
            start += n

    # the top level's tags and the small metadata entries are read through a map; the graph is hashed in chunks
    with mmap.mmap(file.fileno(), 0, access=mmap.ACCESS_READ) as view:
        return _verify(view, size, chunks, where)


def _verify(view, size: int, chunks, where: str | PathLike) -> bool:
    """The check of :func:`check_digest`: ``view`` is read for the top-level fields, ``chunks(start, end)``
    yields the bytes of ``[start, end)`` that are hashed (and searched for a damaged digest entry)."""
    try:
        entries = _digest_entries(view)
    except _Corrupt as err:
        raise NotProtobufError(where, f"its protobuf is corrupt or truncated ({err})") from None
    stored = [value for _, _, value in entries]
    again = "the file was changed or corrupted after export: export it again"
    if len(stored) > 1:
        raise ValueError(f"{where}: the bundle holds {len(stored)} digests ({DIGEST_KEY}); {again}")
    digest, damaged, tail, key, pos = hashlib.sha256(), False, b"", DIGEST_KEY.encode(), 0
    for start, end in [*((s, e) for s, e, _ in entries), (size, size)]:
        for chunk in chunks(pos, start):
            digest.update(chunk)
            if not stored:  # a damaged digest entry: its key or value in the bytes, but not as the property
                window = tail + bytes(chunk)
                damaged = damaged or key in window or _DIGEST_VALUE.search(window) is not None
                tail = window[-80:]
        pos = end
    if not stored:
        if damaged:
            raise ValueError(f"{where}: the bundle's digest entry ({DIGEST_KEY}) is damaged; {again}")
        return False
    expected = DIGEST_PREFIX + digest.hexdigest()
    if stored[0] != expected.encode():
        shown = stored[0][:80].decode("ascii", "replace")
        raise ValueError(
            f"{where}: the bundle's digest does not match its content (stored {shown}, computed {expected}): "
            f"{again}"
        )
    return True


@contextlib.contextmanager
def checked_bundle(path: str | PathLike, *, allow_unsealed: bool = False) -> Iterator[tuple[str, bool]]:
    """Check the bundle ``path`` against its digest; yield ``(what to load, sealed)``; refuse it if it changed.

    What to load is the open file that was checked (``/proc/self/fd/N`` on Linux, else the path), so that
    a file swapped after the check is not the one loaded; a bundle whose size or modification time
    changed while it was in use is refused on exit. A bundle without a digest is refused unless
    ``allow_unsealed`` (``sealed`` is then ``False``).
    """
    import os

    path = Path(path)
    with open(path, "rb") as file:
        before = os.fstat(file.fileno())
        sealed = check_file_digest(file, path)
        if not sealed and not allow_unsealed:
            raise ValueError(
                f"{path}: the bundle has no digest (exported before tactile-torch wrote one, by another tool, "
                "or stripped): its integrity cannot be checked; export it again, or seal a copy you trust "
                "(tactile_torch.robot.integrity.seal_bundle)"
            )
        same = f"/proc/self/fd/{file.fileno()}"
        yield (same if os.path.exists(same) else str(path)), sealed
        after = os.fstat(file.fileno())
    if (after.st_size, after.st_mtime_ns) != (before.st_size, before.st_mtime_ns):
        raise ValueError(f"{path}: the bundle changed while it was loaded: load it again")


def seal_bundle(path: str | PathLike, out: str | PathLike) -> Path:
    """Write a copy of the bundle ``path`` with its digest to ``out``; return ``out``.

    For a bundle without a digest (exported before digests existed) that you trust: the digest then
    guards the copy against later corruption. A bundle whose digest does not match is refused
    (``ValueError``): export it again instead. ``out`` must not be ``path`` (inputs are never
    overwritten).
    """
    from .files.npz import max_read_bytes
    from .files.safe_write import write_atomic

    path = Path(path)
    if path.stat().st_size > max_read_bytes():
        raise ValueError(f"{path}: the bundle is larger than the read limit (TACTILE_TORCH_MAX_READ_MB)")
    data = path.read_bytes()
    check_digest(data, path)
    sealed = seal(data)
    return write_atomic(out, lambda f: f.write(sealed), inputs=[path])


__all__ = [
    "DIGEST_PREFIX",
    "NotProtobufError",
    "UnsealedBundleWarning",
    "check_digest",
    "check_file_digest",
    "checked_bundle",
    "seal",
    "seal_bundle",
]
