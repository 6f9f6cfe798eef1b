"""ROS 2 topics over Cyclone DDS, without a ROS installation: configuration, types, readers, writers.

A ROS 2 topic ``/name`` is the DDS topic ``rt/name``; its type is the DDS type
``pkg::msg::dds_::Name_`` of the ROS message ``pkg/msg/Name``, and its samples are the message's
plain CDR bytes (XCDR1, little-endian), exactly what ``rosbag2`` stores. This module builds the DDS
type of a message from the one set of definitions :func:`tactile_torch.robot.ros2.messages.message_types`
gives (``rosbags``' type store: standard messages, TactileState, a robot's own ``.msg`` text), and moves
the CDR bytes in and out unchanged: ``rosbags`` decodes and encodes them, as it does for bags.

Network rule. The configuration the tool ships (:func:`loopback_config`, ``"loopback"``) keeps DDS on
this machine's loopback: the ``lo`` interface only, multicast off, unicast discovery to 127.0.0.1 only.
It is the default when neither a configuration nor ``CYCLONEDDS_URI`` is given (:func:`resolve_config`),
and every test and documented command uses it. A deployment points it at the robot's network with its
own Cyclone DDS XML (a file, or ``CYCLONEDDS_URI`` as for any ROS 2 program using Cyclone DDS).

``cyclonedds`` (the optional extra ``ros2``, :data:`ROS2_EXTRA`) is imported inside the functions that
need it: importing this module costs nothing on a robot without it.
"""

from __future__ import annotations

import os
import sys
from dataclasses import dataclass
from pathlib import Path

from .message_types import import_extra, ros_type_name

ROS2_EXTRA = "ros2"
"""The optional extra that installs ``cyclonedds`` (and ``rosbags``, for the message definitions)."""
LOOPBACK = "loopback"
"""The name of the configuration the tool ships: DDS on this machine's loopback only."""
MAX_DOMAIN_ID = 232
"""The largest DDS domain id (its ports must fit below 65536); ROS 2 uses 0-101 and 215-232 on Linux."""
LOOPBACK_PARTICIPANTS = 32
"""DDS participants (processes) one domain of the loopback configuration holds on this machine."""
QOS_PROFILES = ("sensor", "lossless")
"""Reader (and publisher) QoS: ``"sensor"`` (best effort, as ROS 2's sensor-data profile; a message the
reader has no room for is lost and counted) or ``"lossless"`` (reliable, keep all: a publisher that the
reader cannot keep up with is held back, nothing is lost while its own history lasts)."""
WRITER_PROFILES = (*QOS_PROFILES, "reliable")
"""Writer QoS: those of :data:`QOS_PROFILES`, and ``"reliable"`` (keep the last ``depth``: the decisions)."""
DEFAULT_DEPTH = 1000
"""Messages the reader queues until the stream takes them: about 1 s of a 1 kHz array."""
DEFAULT_LEASE_S = 10.0
"""A DDS participant's lease when its publisher does not say (Cyclone DDS's default, and ROS 2's with it):
a publisher that was killed is seen to leave when its lease ends."""
LOSSLESS_BLOCKING_S = 10.0
"""How long a ``"lossless"`` publisher waits for room in its readers' queues before a write fails."""
DECISION_DEPTH = 100
"""Decisions the decision writer keeps for late acknowledgements (reliable, keep last)."""
MAX_CONFIG_BYTES = 1 << 20
"""Largest Cyclone DDS configuration file read."""


def cyclonedds_module(what: str = "ROS 2 topics"):
    """Import ``cyclonedds`` (its C library), or raise :class:`MissingExtraError` saying that ``what`` needs the extra."""
    import_extra("cyclonedds.domain", ROS2_EXTRA, what)
    return import_extra("cyclonedds", ROS2_EXTRA, what)


def loopback_interface() -> str:
    """Return the name of this machine's loopback interface (``lo`` on Linux, ``lo0`` on macOS and BSD)."""
    return "lo" if sys.platform.startswith("linux") else "lo0"


def loopback_config(*, max_participants: int = LOOPBACK_PARTICIPANTS, trace_file: str | None = None) -> str:
    """Return the Cyclone DDS XML that keeps discovery and data on this machine's loopback.

    The loopback interface only, multicast off, unicast discovery to 127.0.0.1 only (participant
    indices 0 to ``max_participants - 1``, one per process on a domain). ``trace_file`` adds Cyclone's
    ``config`` trace (the effective configuration and the interfaces and peers it selected) written
    there, which is how the tests check the rule.

    >>> "<AllowMulticast>false</AllowMulticast>" in loopback_config()
    True
    """
    trace = ""
    if trace_file is not None:
        trace = f"<Tracing><Verbosity>config</Verbosity><OutputFile>{_xml_text(trace_file)}</OutputFile></Tracing>"
    return (
        '<CycloneDDS xmlns="https://cdds.io/config"><Domain Id="any">'
        f'<General><Interfaces><NetworkInterface name="{loopback_interface()}"/></Interfaces>'
        "<AllowMulticast>false</AllowMulticast></General>"
        '<Discovery><Peers><Peer address="127.0.0.1"/></Peers><ParticipantIndex>auto</ParticipantIndex>'
        f"<MaxAutoParticipantIndex>{int(max_participants) - 1}</MaxAutoParticipantIndex></Discovery>"
        f"{trace}</Domain></CycloneDDS>"
    )


def _xml_text(text: str) -> str:
    return text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")


def resolve_config(config: str | None = None, *, environ=os.environ) -> tuple[str, str]:
    """Return ``(xml_or_uri, description)`` of the Cyclone DDS configuration to use.

    ``config``: ``"loopback"`` (:func:`loopback_config`), a path to an XML file, or XML text
    (starting with ``<``). ``None``: ``CYCLONEDDS_URI`` when it is set (as every ROS 2 program using
    Cyclone DDS does), else the loopback configuration. The description says which, for the
    stream's first line.

    Raises
    ------
    FileNotFoundError
        A path that does not exist.
    ValueError
        A file larger than :data:`MAX_CONFIG_BYTES`.
    """
    if config is None:
        uri = environ.get("CYCLONEDDS_URI", "").strip()
        if uri:
            return uri, "CYCLONEDDS_URI"
        config = LOOPBACK
    if config == LOOPBACK:
        return loopback_config(), "loopback only (127.0.0.1, multicast off)"
    if config.lstrip().startswith("<"):
        return config, "the XML given"
    path = Path(config.removeprefix("file://"))
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such Cyclone DDS configuration file (or 'loopback')")
    if path.stat().st_size > MAX_CONFIG_BYTES:
        raise ValueError(f"{path}: more than {MAX_CONFIG_BYTES} bytes, not a Cyclone DDS configuration")
    return path.read_text(encoding="utf-8"), str(path)


def check_domain_id(domain_id: int) -> int:
    """Return ``domain_id`` if it is a DDS domain id (0 to :data:`MAX_DOMAIN_ID`), else raise ``ValueError``."""
    if isinstance(domain_id, bool) or not isinstance(domain_id, int) or not 0 <= domain_id <= MAX_DOMAIN_ID:
        raise ValueError(f"domain_id must be an int in 0..{MAX_DOMAIN_ID}, got {domain_id!r}")
    return domain_id


def default_domain_id(environ=os.environ) -> int:
    """Return ``ROS_DOMAIN_ID`` when set (as ROS 2 programs do), else 0."""
    text = environ.get("ROS_DOMAIN_ID", "").strip()
    if not text:
        return 0
    if not text.isdigit():
        raise ValueError(f"ROS_DOMAIN_ID must be a domain id in 0..{MAX_DOMAIN_ID}, got {text!r}")
    return check_domain_id(int(text))


def dds_topic_name(topic: str) -> str:
    """Return the DDS topic of the ROS 2 topic ``topic``.

    >>> dds_topic_name("/hand/tactile")
    'rt/hand/tactile'
    """
    name = str(topic).strip()
    if not name.startswith("/") or name == "/" or "//" in name or name.endswith("/"):
        raise ValueError(f"topic must be an absolute ROS 2 topic name such as /hand/tactile, got {topic!r}")
    return "rt" + name


def dds_type_name(msgtype: str) -> str:
    """Return the DDS type name of a ROS 2 message type.

    >>> dds_type_name("sensor_msgs/msg/Imu")
    'sensor_msgs::msg::dds_::Imu_'
    """
    pkg, _, name = ros_type_name(msgtype).split("/")
    return f"{pkg}::msg::dds_::{name}_"


def ros_type_of(dds_name: str) -> str | None:
    """Return the ROS 2 message type of a DDS type name, ``None`` if it is not one.

    >>> ros_type_of("tactile_msgs::msg::dds_::TactileState_")
    'tactile_msgs/msg/TactileState'
    """
    parts = str(dds_name).split("::")
    if len(parts) != 4 or parts[2] != "dds_" or not parts[3].endswith("_"):
        return None
    return f"{parts[0]}/{parts[1]}/{parts[3][:-1]}"


class DdsTypes:
    """The Cyclone DDS types of the messages of one ``rosbags`` type store, built on first use.

    Each message type ``pkg/msg/Name`` becomes a final, keyless IDL struct named
    ``pkg::msg::dds_::Name_`` with the fields of its definition in order (nested messages, arrays,
    bounded and unbounded sequences and strings), which is the type ``rosidl`` generates for DDS. A
    topic's type (:meth:`topic_type`) carries its samples as CDR bytes (:class:`CdrSample`):
    ``rosbags`` encodes and decodes them.
    """

    def __init__(self, store) -> None:
        self.store = store
        self._structs: dict[str, type] = {}
        self._topic_types: dict[str, type] = {}

    def struct(self, msgtype: str) -> type:
        """Return the IDL struct of ``msgtype`` (its fields typed; for nesting and type information)."""
        if msgtype not in self._structs:
            from cyclonedds.idl import make_idl_struct

            pkg, _, name = msgtype.split("/")
            fields = {field: self._field_type(node) for field, node in self.store.fielddefs[msgtype][1]}
            self._structs[msgtype] = make_idl_struct(name, f"{pkg}.msg.dds_.{name}_", fields)
        return self._structs[msgtype]

    def _field_type(self, node):
        from cyclonedds.idl import types
        from rosbags.typesys.base import Nodetype

        kind, arg = node
        if kind == Nodetype.BASE:
            name, bound = arg
            if name == "string":
                return types.bounded_str[bound] if bound else str
            return _BASE_TYPES[name](types)
        if kind == Nodetype.NAME:
            return self.struct(arg)
        inner, size = arg
        if kind == Nodetype.ARRAY:
            return types.array[self._field_type(inner), size]
        return (
            types.sequence[self._field_type(inner), size] if size else types.sequence[self._field_type(inner)]
        )

    def topic_type(self, msgtype: str) -> type:
        """Return the type a topic of ``msgtype`` is created with: samples in and out as CDR bytes."""
        if msgtype not in self._topic_types:
            from cyclonedds.idl import IdlMeta, IdlStruct

            struct = self.struct(msgtype)
            pkg, _, name = msgtype.split("/")
            namespace = IdlMeta.__prepare__(name, (IdlStruct,), typename=f"{pkg}.msg.dds_.{name}_")
            namespace["__annotations__"].update(struct.__annotations__)
            namespace["serialize"] = _serialize_cdr
            namespace["deserialize"] = classmethod(_deserialize_cdr)
            namespace["deserialize_key"] = classmethod(_no_key)  # a keyless type: a writer's leaving notice
            self._topic_types[msgtype] = IdlMeta(name, (IdlStruct,), namespace)
        return self._topic_types[msgtype]

    def sample(self, msgtype: str, cdr: bytes) -> object:
        """Return a sample of the topic type of ``msgtype`` holding the CDR bytes ``cdr`` (with their header)."""
        sample = self.topic_type(msgtype).__new__(self.topic_type(msgtype))
        sample.cdr = bytes(cdr)
        return sample


_BASE_TYPES = {
    "bool": lambda t: bool,
    "byte": lambda t: t.uint8,
    "char": lambda t: t.uint8,  # ROS 2's char is an unsigned 8-bit integer, as rosidl maps it
    "int8": lambda t: t.int8,
    "uint8": lambda t: t.uint8,
    "int16": lambda t: t.int16,
    "uint16": lambda t: t.uint16,
    "int32": lambda t: t.int32,
    "uint32": lambda t: t.uint32,
    "int64": lambda t: t.int64,
    "uint64": lambda t: t.uint64,
    "float32": lambda t: t.float32,
    "float64": lambda t: t.float64,
}


class CdrSample:
    """A received sample: its CDR bytes (with the 4-byte encapsulation header) and Cyclone's sample info."""

    __slots__ = ("cdr", "sample_info")

    def __init__(self, cdr: bytes) -> None:
        self.cdr = cdr
        self.sample_info = None


def _serialize_cdr(self, buffer=None, endianness=None, use_version_2=None) -> bytes:
    return self.cdr


def _deserialize_cdr(cls, data, has_header=True, use_version_2=None) -> CdrSample:
    return CdrSample(bytes(data))


def _no_key(cls, data, has_header=True, use_version_2=None) -> None:
    return None


def qos(profile: str = "sensor", depth: int = DEFAULT_DEPTH):
    """Return the Cyclone DDS QoS of a reader or writer (volatile, as ROS 2's profiles are).

    ``"sensor"``: best effort, keep all up to ``depth`` messages (a reader's queue that is full
    rejects the newest, which Cyclone counts: the stream reports them as lost, where a keep-last
    queue would overwrite the oldest unsaid). ``"lossless"``: reliable, keep all up to ``depth``
    messages: a full reader's queue holds the publisher back (its writes wait up to
    :data:`LOSSLESS_BLOCKING_S`). ``"reliable"`` (writers): reliable, keep the last ``depth``.
    ROS 2's sensor-data profile keeps 5: a classifier needs every frame, so the reader keeps more,
    which changes nothing on the wire.
    """
    from cyclonedds.core import Policy, Qos
    from cyclonedds.util import duration

    if profile not in WRITER_PROFILES:
        raise ValueError(f"qos must be one of {QOS_PROFILES}, got {profile!r}")
    depth = int(depth)
    if profile == "sensor":
        reliability = Policy.Reliability.BestEffort
    else:
        blocking = LOSSLESS_BLOCKING_S if profile == "lossless" else 0.1
        reliability = Policy.Reliability.Reliable(max_blocking_time=duration(seconds=blocking))
    if profile == "reliable":
        return Qos(reliability, Policy.History.KeepLast(depth), Policy.Durability.Volatile)
    limits = Policy.ResourceLimits(max_samples=depth, max_instances=-1, max_samples_per_instance=depth)
    return Qos(reliability, Policy.History.KeepAll, limits, Policy.Durability.Volatile)


@dataclass(frozen=True)
class DdsOptions:
    """Where and how to reach ROS 2 topics over DDS (the ``stream`` and ``simulate-sensor`` options).

    Attributes
    ----------
    domain_id : int or None
        DDS domain (ROS 2's ``ROS_DOMAIN_ID``); ``None``: ``ROS_DOMAIN_ID``, else 0.
    config : str or None
        ``"loopback"``, an XML file or XML text; ``None``: ``CYCLONEDDS_URI``, else loopback
        (:func:`resolve_config`).
    qos : {"sensor", "lossless"}
        Reliability of the data reader or writer (:func:`qos`).
    depth : int
        Messages a reader queues until they are taken (a writer keeps as many).
    """

    domain_id: int | None = None
    config: str | None = None
    qos: str = "sensor"
    depth: int = DEFAULT_DEPTH


class DdsNode:
    """A DDS participant on one domain, configured by :class:`DdsOptions`; a context manager.

    Closing it deletes every reader and writer made from it: their peers see them leave at once
    (a process that is killed is seen to leave when its lease ends, 10 s by Cyclone DDS's default).
    """

    def __init__(self, options: DdsOptions = DdsOptions()) -> None:
        cyclonedds_module()
        from cyclonedds.domain import Domain, DomainParticipant

        self.domain_id = (
            default_domain_id() if options.domain_id is None else check_domain_id(options.domain_id)
        )
        if options.qos not in QOS_PROFILES:
            raise ValueError(f"qos must be one of {QOS_PROFILES}, got {options.qos!r}")
        xml, self.config_description = resolve_config(options.config)
        self.options = options
        try:
            self._domain = Domain(self.domain_id, xml)
            self.participant = DomainParticipant(self.domain_id)
        except Exception as err:  # DDSException: a configuration Cyclone refuses, no free participant index
            raise ValueError(
                f"DDS could not start on domain {self.domain_id} with {self.config_description} ({err})"
            ) from None
        self._entities: list = [self.participant, self._domain]

    def __enter__(self) -> DdsNode:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Delete the participant and all it holds."""
        from cyclonedds.core import Entity

        for entity in self._entities:
            ref = getattr(entity, "_ref", None)
            if ref is not None and ref in Entity._entities:
                del Entity._entities[ref]
                entity._delete(ref)
        self._entities = []

    def topic(self, topic: str, msgtype: str, types: DdsTypes):
        """Return the DDS topic of the ROS 2 topic ``topic`` of type ``msgtype``."""
        from cyclonedds.topic import Topic

        return Topic(self.participant, dds_topic_name(topic), types.topic_type(msgtype))

    def writer(
        self,
        topic: str,
        msgtype: str,
        types: DdsTypes,
        *,
        profile: str | None = None,
        depth: int | None = None,
    ):
        """Return a data writer of ``topic``; ``write(types.sample(msgtype, cdr))`` publishes one message."""
        from cyclonedds.pub import DataWriter

        writer_qos = qos(profile or self.options.qos, depth or self.options.depth)
        return DataWriter(self.participant, self.topic(topic, msgtype, types), qos=writer_qos)

    def publications(self, topic: str) -> list[str]:
        """Return the DDS type names of the publications of ``topic`` this participant has discovered."""
        return sorted({p.type_name for p in self.publishers(topic)})

    def publishers(self, topic: str) -> list[Publication]:
        """Return the publications of ``topic`` this participant has discovered (alive now), with their lease."""
        from cyclonedds.builtin import (
            BuiltinDataReader,
            BuiltinTopicDcpsParticipant,
            BuiltinTopicDcpsPublication,
        )
        from cyclonedds.core import InstanceState, Policy

        if not hasattr(self, "_publications"):
            self._publications = BuiltinDataReader(self.participant, BuiltinTopicDcpsPublication)
            self._participants = BuiltinDataReader(self.participant, BuiltinTopicDcpsParticipant)
            self._known: dict = {}
            self._leases: dict = {}
        for sample in self._participants.take(64):
            info, qos_ = getattr(sample, "sample_info", None), getattr(sample, "qos", None)
            if info is not None and info.instance_state == InstanceState.Alive and qos_ is not None:
                try:
                    self._leases[sample.key] = qos_[Policy.Liveliness].lease_duration * 1e-9
                except (KeyError, AttributeError):  # a participant that states no lease: Cyclone's default
                    self._leases[sample.key] = DEFAULT_LEASE_S
        for sample in self._publications.take(64):
            info = getattr(sample, "sample_info", None)
            if info is not None and info.instance_state != InstanceState.Alive:
                self._known.pop(info.instance_handle, None)
            elif getattr(sample, "key", None) is not None:
                self._known[info.instance_handle] = (
                    sample.topic_name,
                    sample.type_name,
                    sample.participant_key,
                )
        name = dds_topic_name(topic)
        return [
            Publication(instance_handle(handle), type_name, self._leases.get(key, DEFAULT_LEASE_S))
            for handle, (topic_name, type_name, key) in self._known.items()
            if topic_name == name
        ]


def instance_handle(handle: int) -> int:
    """A DDS instance handle as one number (Cyclone gives the same handle signed or unsigned, by the call)."""
    return int(handle) % 2**64


@dataclass(frozen=True)
class Publication:
    """A publication (a data writer) of a topic, as DDS discovery describes it.

    Attributes
    ----------
    handle : int
        Its instance handle: the ``publisher`` of the messages it sends (:attr:`Received.publisher`).
    type_name : str
        Its DDS type name (``ros_type_of`` gives the ROS 2 message type).
    lease_s : float
        Its participant's lease: a publisher whose process was killed is seen to leave this long after.
    """

    handle: int
    type_name: str
    lease_s: float


__all__ = [
    "DECISION_DEPTH",
    "DEFAULT_DEPTH",
    "DEFAULT_LEASE_S",
    "LOOPBACK",
    "LOOPBACK_PARTICIPANTS",
    "LOSSLESS_BLOCKING_S",
    "MAX_DOMAIN_ID",
    "QOS_PROFILES",
    "ROS2_EXTRA",
    "WRITER_PROFILES",
    "CdrSample",
    "DdsNode",
    "DdsOptions",
    "DdsTypes",
    "Publication",
    "check_domain_id",
    "cyclonedds_module",
    "dds_topic_name",
    "dds_type_name",
    "default_domain_id",
    "instance_handle",
    "loopback_config",
    "loopback_interface",
    "qos",
    "resolve_config",
    "ros_type_of",
]
