"""ROS 2 message types from one place: rosbags' type store, TactileState, and a robot's own ``.msg`` text.

:func:`message_types` returns the type store every ROS 2 reader and writer of the package uses: the
standard messages of ROS 2 Humble as ``rosbags`` defines them, ``tactile_msgs/msg/TactileState`` from its
``.msg`` text (:data:`TACTILE_STATE_MSG`), and the messages a robot defines (:class:`MessageDefinition`,
read from ``.msg`` files by :func:`read_message_definition`). The bag reader decodes with it, the DDS
layer (:mod:`tactile_torch.robot.ros2.dds`) turns its definitions into Cyclone DDS types, and
:mod:`tactile_torch.robot.ros2.messages` turns its messages into values and back.

``rosbags`` is the optional extra ``ros`` (:data:`ROS_EXTRA`), imported inside the functions that need it.
"""

from __future__ import annotations

import keyword
import os
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

PathLike = str | os.PathLike

ROS_EXTRA = "ros"
"""The optional extra that installs ``rosbags`` (bags, and the message definitions of live topics)."""

IMU_TYPE = "sensor_msgs/msg/Imu"
FLOAT_ARRAY_TYPE = "std_msgs/msg/Float32MultiArray"
IMAGE_TYPE = "sensor_msgs/msg/Image"
TACTILE_STATE_TYPE = "tactile_msgs/msg/TactileState"
STRING_TYPE = "std_msgs/msg/String"
FRAME_TYPES = (FLOAT_ARRAY_TYPE, IMAGE_TYPE, TACTILE_STATE_TYPE)
"""The standard message types that carry one frame (a pressure map) per message."""
STANDARD_TYPES = (IMU_TYPE, *FRAME_TYPES)
"""The message types read without a ``field``."""

TACTILE_STATE_MSG = """\
# tactile_msgs/msg/TactileState (ubi-agni/tactile_toolbox): the state of a hand's tactile sensors,
# one channel of taxel values per sensor.
std_msgs/Header header
sensor_msgs/ChannelFloat32[] sensors
"""
"""The ``.msg`` text of ``tactile_msgs/msg/TactileState``, the de facto tactile message of ROS hands."""

MAX_MSG_DEF_BYTES = 64 * 1024
"""Largest ``.msg`` file read (a message definition is a few hundred bytes)."""
MAX_MESSAGE_DEPTH = 32
"""Deepest nesting of message types read (a message holding a message holding ...): ROS's own reach 5."""

_TYPE_NAME = re.compile(r"^([A-Za-z][A-Za-z0-9_]*)/(?:msg/)?([A-Za-z][A-Za-z0-9_]*)$")
_IDENTIFIER = r"[A-Za-z][A-Za-z0-9_]*"
_MSG_LINE = re.compile(
    rf"^\s*(?:{_IDENTIFIER}/)*{_IDENTIFIER}(?:<=\d+)?(?:\[(?:<=)?\d*\])?\s+({_IDENTIFIER})\s*(?:=.*|\s.*)?$"
)
"""A field or constant line of a ``.msg`` definition: ``TYPE NAME``, ``TYPE NAME DEFAULT``, ``TYPE NAME=VALUE``."""
_SEPARATOR = re.compile(r"^(?:=+|MSG: \S+)\s*$")
"""The lines between the definitions of a message and the ones it uses (as ``rosbag2`` stores them)."""


class MissingExtraError(ImportError, ValueError):
    """An optional extra is not installed (an ``ImportError``; a ``ValueError`` so the CLI prints one line)."""


def import_extra(module: str, extra: str, what: str):
    """Import ``module`` of an optional extra, or raise :class:`MissingExtraError` saying that ``what`` needs it."""
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError as err:
        package = module.split(".")[0]
        raise MissingExtraError(
            f"{what} needs the optional extra {extra!r} (the {package} package), which is not installed: "
            f"pip install 'tactile-torch[{extra}]'",
            name=package,
        ) from err


def rosbags_module(what: str = "reading ROS 2 messages"):
    """Import ``rosbags.typesys``, or raise :class:`MissingExtraError` saying that ``what`` needs the extra."""
    return import_extra("rosbags.typesys", ROS_EXTRA, what)


def ros_type_name(name: str) -> str:
    """Return the full ROS 2 name ``pkg/msg/Name`` of ``pkg/Name`` or ``pkg/msg/Name``.

    >>> ros_type_name("sensor_msgs/Imu")
    'sensor_msgs/msg/Imu'
    """
    match = _TYPE_NAME.match(str(name).strip())
    if match is None:
        raise ValueError(
            f"a message type must be named pkg/msg/Name (e.g. sensor_msgs/msg/Imu), got {name!r}"
        )
    return f"{match.group(1)}/msg/{match.group(2)}"


@dataclass(frozen=True)
class MessageDefinition:
    """The ``.msg`` text of a message type a robot defines.

    Attributes
    ----------
    text : str
        The definition, as in the package's ``msg/Name.msg``.
    name : str or None
        ``pkg/msg/Name``; ``None`` when it is to be taken from the topic (the bag's or the live
        publisher's type).
    source : str
        Where the text came from (for messages).
    """

    text: str
    name: str | None = None
    source: str = "<text>"


def read_message_definition(path: PathLike, name: str | None = None) -> MessageDefinition:
    """Return the message definition in the ``.msg`` file ``path``.

    The type's name is ``name``, else taken from a path that ends in ``<pkg>/msg/<Name>.msg`` (as
    in a ROS 2 package), else left to the topic that is read. ``name`` may also be given in
    ``path`` itself as ``pkg/msg/Name=FILE``. Reads at most :data:`MAX_MSG_DEF_BYTES` bytes.

    Raises
    ------
    FileNotFoundError
        If the file does not exist.
    ValueError
        A directory, FIFO or device; a file larger than :data:`MAX_MSG_DEF_BYTES`, not UTF-8 text, or a bad ``name``.
    """
    from ..files.npz import check_file

    text_path = str(path)
    if name is None and "=" in text_path and not Path(text_path).exists():
        name, text_path = text_path.split("=", 1)
    file = Path(text_path)
    if not file.exists():
        raise FileNotFoundError(f"{file}: no such message definition (.msg) file")
    check_file(file, "a message definition (.msg) file")
    size = file.stat().st_size
    if size > MAX_MSG_DEF_BYTES:
        raise ValueError(f"{file}: {size} bytes, more than the {MAX_MSG_DEF_BYTES} of a message definition")
    try:
        text = file.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise ValueError(f"{file}: a message definition must be UTF-8 text") from None
    if name is None and file.parent.name == "msg" and file.suffix == ".msg":
        name = f"{file.parent.parent.name}/msg/{file.stem}"
    definition = MessageDefinition(text, None if name is None else ros_type_name(name), str(file))
    _check_text(definition)  # refused as soon as it is read, before anything is built from it
    return definition


def _check_text(definition: MessageDefinition) -> None:
    """Refuse a definition whose lines are not fields, constants or separators, or that names a field or a
    type with a Python keyword (the DDS and decoding types are built from the names): one line, quoting
    at most the offending line."""
    for number, raw in enumerate(definition.text.splitlines(), start=1):
        line = raw.split("#", 1)[0].strip()
        if not line or _SEPARATOR.match(line):
            continue
        match = _MSG_LINE.match(line)
        shown = raw.strip()[:80] + ("..." if len(raw.strip()) > 80 else "")
        if match is None:
            raise ValueError(
                f"{definition.source} line {number}: not a field of a message definition (TYPE NAME): {shown!r}"
            )
        names = [match[1], *re.findall(_IDENTIFIER, line.split()[0])]
        keywords = [n for n in names if keyword.iskeyword(n)]
        if keywords:
            raise ValueError(
                f"{definition.source} line {number}: {keywords[0]!r} is a Python keyword, which the message "
                f"types cannot be built with (rename the field or type): {shown!r}"
            )


def _check_nesting(store, names: Sequence[str]) -> None:
    """Refuse a message that holds itself (directly or through others), or nests deeper than :data:`MAX_MESSAGE_DEPTH`."""
    depth: dict[str, int] = {}
    for root in names:
        path, stack = [root], [iter(_nested_names(store.fielddefs[root][1]))]
        while stack:
            child = next(stack[-1], None)
            if child is None:
                done = path.pop()
                stack.pop()
                kids = _nested_names(store.fielddefs[done][1]) if done in store.fielddefs else []
                depth[done] = 1 + max((depth.get(k, 0) for k in kids), default=0)
                continue
            if child in path:
                cycle = " -> ".join([*path[path.index(child) :], child])
                raise ValueError(f"the message type {child} holds itself ({cycle}): a ROS 2 message cannot")
            if child in depth or child not in store.fielddefs:
                continue
            if len(path) >= MAX_MESSAGE_DEPTH:
                raise ValueError(
                    f"the message type {root} nests messages more than {MAX_MESSAGE_DEPTH} deep "
                    f"({' -> '.join(path[:3])} -> ... -> {path[-1]})"
                )
            path.append(child)
            stack.append(iter(_nested_names(store.fielddefs[child][1])))


def message_types(definitions: Sequence[MessageDefinition] = (), *, topic_type: str | None = None):
    """Return a fresh ``rosbags`` type store: ROS 2's standard messages, TactileState, and ``definitions``.

    Parameters
    ----------
    definitions : sequence of MessageDefinition
        Messages a robot defines. One without a name is registered as ``topic_type``.
    topic_type : str, optional
        The type of the topic being read (from the bag or the live publisher).

    Raises
    ------
    MissingExtraError
        Without ``rosbags``.
    ValueError
        A definition that does not parse, one without a name when there is no ``topic_type`` (or
        several without one), or a name already defined otherwise.
    """
    typesys = rosbags_module()
    store = typesys.get_typestore(typesys.Stores.ROS2_HUMBLE)
    store.register(typesys.get_types_from_msg(TACTILE_STATE_MSG, TACTILE_STATE_TYPE))
    unnamed = [d for d in definitions if d.name is None]
    if len(unnamed) > 1 or (unnamed and topic_type is None):
        raise ValueError(
            f"the message definition {unnamed[0].source} does not say which type it defines: name it "
            "pkg/msg/Name=FILE or keep it as pkg/msg/Name.msg"
        )
    defined = []
    for definition in definitions:
        name = definition.name or ros_type_name(topic_type)
        _check_text(definition)  # before any code is generated from its names
        try:
            types = typesys.get_types_from_msg(definition.text, name)
        except Exception as err:  # rosbags raises its own TypesysError, or a parser error, quoting the text
            raise ValueError(
                f"{definition.source}: not a message definition rosbags can read for {name} "
                f"({type(err).__name__})"
            ) from None
        for typename in types:
            pkg, _, short = typename.split("/")
            bad = [n for n in (pkg, short) if keyword.iskeyword(n)]
            if bad:
                raise ValueError(
                    f"{definition.source}: the type {typename} is named with the Python keyword {bad[0]!r}"
                )
        try:
            store.register(types)
        except Exception as err:  # a type already defined otherwise
            raise ValueError(f"{definition.source}: {' '.join(str(err).split())[:200]}") from None
        defined += list(types)
    _check_nesting(store, defined)
    return store


def has_type(store, msgtype: str) -> bool:
    """Return whether the type store knows ``msgtype`` and every type its fields use."""
    fielddefs = store.fielddefs
    todo, seen = [msgtype], set()
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        seen.add(name)
        if name not in fielddefs:
            return False
        todo.extend(_nested_names(fielddefs[name][1]))
    return True


def _nested_names(fields) -> list[str]:
    from rosbags.typesys.base import Nodetype

    names = []
    for _, (kind, arg) in fields:
        while kind in (Nodetype.ARRAY, Nodetype.SEQUENCE):
            kind, arg = arg[0]
        if kind == Nodetype.NAME:
            names.append(arg)
    return names


NUMPY_DTYPES = {
    "bool": np.bool_,
    "byte": np.uint8,
    "char": np.uint8,
    "int8": np.int8,
    "uint8": np.uint8,
    "int16": np.int16,
    "uint16": np.uint16,
    "int32": np.int32,
    "uint32": np.uint32,
    "int64": np.int64,
    "uint64": np.uint64,
    "float32": np.float32,
    "float64": np.float64,
}


def default_message(store, msgtype: str):
    """Return a message of ``msgtype`` whose fields hold zeros, empty strings and empty sequences."""
    fields = {name: _default_value(store, node) for name, node in store.fielddefs[msgtype][1]}
    return store.types[msgtype](**fields)


def _default_value(store, node):
    from rosbags.typesys.base import Nodetype

    kind, arg = node
    if kind == Nodetype.BASE:
        name = arg[0]
        return "" if name == "string" else NUMPY_DTYPES[name](0).item()
    if kind == Nodetype.NAME:
        return default_message(store, arg)
    (inner_kind, inner), size = arg
    if kind == Nodetype.SEQUENCE:
        size = 0
    if inner_kind == Nodetype.BASE and inner[0] != "string":
        return np.zeros(size, dtype=NUMPY_DTYPES[inner[0]])
    return [_default_value(store, (inner_kind, inner)) for _ in range(size)]


def has_header(store, msgtype: str) -> bool:
    return any(
        name == "header" and arg == "std_msgs/msg/Header" for name, (_, arg) in store.fielddefs[msgtype][1]
    )


def check_field_path(store, msgtype: str, path: str) -> None:
    """Refuse a field path that does not lead through messages to a field of msgtype's definition."""
    from rosbags.typesys.base import Nodetype

    current = msgtype
    parts = path.split(".")
    for i, part in enumerate(parts):
        fields = dict(store.fielddefs[current][1])
        if part not in fields:
            raise ValueError(
                f"{current} has no field {part!r} (field={path!r}); its fields: {', '.join(fields) or 'none'}"
            )
        kind, arg = fields[part]
        if i < len(parts) - 1:
            if kind != Nodetype.NAME:
                raise ValueError(
                    f"field={path!r}: {current}.{part} is not a message, so it has no field {parts[i + 1]!r}"
                )
            current = arg


__all__ = [
    "FLOAT_ARRAY_TYPE",
    "FRAME_TYPES",
    "IMAGE_TYPE",
    "IMU_TYPE",
    "MAX_MESSAGE_DEPTH",
    "MAX_MSG_DEF_BYTES",
    "NUMPY_DTYPES",
    "ROS_EXTRA",
    "STANDARD_TYPES",
    "STRING_TYPE",
    "TACTILE_STATE_MSG",
    "TACTILE_STATE_TYPE",
    "MessageDefinition",
    "MissingExtraError",
    "check_field_path",
    "default_message",
    "has_header",
    "has_type",
    "import_extra",
    "message_types",
    "read_message_definition",
    "ros_type_name",
    "rosbags_module",
]
