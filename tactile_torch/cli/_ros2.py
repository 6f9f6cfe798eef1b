"""The ROS 2 options of ``stream`` and ``simulate-sensor``, and ``simulate-sensor --ros2-topic``.

Torch-free: the robot runs them with ``cyclonedds`` and ``rosbags`` (the extra ``ros2``), imported inside
the functions. DDS stays on this machine's loopback unless ``--dds-config`` or ``CYCLONEDDS_URI`` says
otherwise (:func:`tactile_torch.robot.ros2.dds.resolve_config`).
"""

from __future__ import annotations

import argparse
import sys

from ._options import UsageError, add_msg_def, at_least, message_definitions


def add_dds_options(p: argparse.ArgumentParser, *, reader: bool) -> argparse._ArgumentGroup:
    """Add the options of a ROS 2 topic over DDS (``--ros2-topic`` and how to reach it) to ``p``; return the group."""
    g = p.add_argument_group("ROS 2 topics over Cyclone DDS (docs/stream.md, 'ROS 2 topics')")
    g.add_argument(
        "--ros2-topic",
        default=None,
        metavar="TOPIC",
        help="a ROS 2 topic, e.g. /hand/tactile, instead of --port"
        + (" (needs the extra ros2: pip install 'tactile-torch[ros2]')" if reader else ""),
    )
    g.add_argument(
        "--ros2-type",
        default=None,
        metavar="TYPE",
        help="its message type, pkg/msg/Name (default: "
        + (
            "the publisher's"
            if reader
            else "sensor_msgs/msg/Imu for recordings, std_msgs/msg/Float32MultiArray for frames"
        )
        + ")",
    )
    g.add_argument(
        "--field",
        default=None,
        help="the dotted path of the field that holds the numbers, for a message type of your own "
        "(e.g. taxels.values)",
    )
    g.add_argument(
        "--sensor",
        default=None,
        metavar="NAME",
        help="tactile_msgs/msg/TactileState: the sensor (channel) "
        + (
            "to read (default: the only one); all: every sensor of the hand, each cut into touches of its own "
            "(and, with --port, a line that holds the frames of several arrays)"
            if reader
            else "to publish (default: tactile)"
        ),
    )
    add_msg_def(g)
    g.add_argument(
        "--domain-id",
        type=at_least(0, int),
        default=None,
        help="DDS domain (default: ROS_DOMAIN_ID, else 0)",
    )
    g.add_argument(
        "--dds-config",
        default=None,
        metavar="FILE",
        help="Cyclone DDS XML for your network, or 'loopback' (default: CYCLONEDDS_URI when set, else "
        "loopback: this machine only, 127.0.0.1, multicast off)",
    )
    g.add_argument(
        "--qos",
        default="sensor",
        choices=["sensor", "lossless"],
        help="sensor: best effort, ROS 2's sensor-data profile (what the stream cannot take is lost, counted and "
        "said); lossless: reliable, keep all (a publisher the stream cannot keep up with is held back; at most "
        "--qos-depth messages queued) (default: sensor)",
    )
    return g


def dds_options(args: argparse.Namespace):
    """Return the :class:`~tactile_torch.robot.ros2.dds.DdsOptions` the parsed arguments declare."""
    from ..robot.ros2.dds import DEFAULT_DEPTH, DdsOptions

    return DdsOptions(
        domain_id=args.domain_id,
        config=args.dds_config,
        qos=args.qos,
        depth=getattr(args, "qos_depth", None) or DEFAULT_DEPTH,
    )


def topic_fields(args: argparse.Namespace, msgtype: str):
    """Return the :class:`~tactile_torch.robot.ros2.messages.TopicFields` of ``msgtype`` and the options."""
    from ..robot.ros2.message_types import ros_type_name
    from ..robot.ros2.messages import TopicFields

    return TopicFields(ros_type_name(msgtype), args.field, args.sensor)


def add_publisher_options(g: argparse._ArgumentGroup) -> None:
    """Add the options only ``simulate-sensor --ros2-topic`` has to its ROS 2 group ``g``."""
    g.add_argument(
        "--encoding",
        default="32FC1",
        choices=["32FC1", "mono16", "mono8"],
        help="sensor_msgs/msg/Image: the encoding (mono16 and mono8 take whole numbers; default: 32FC1)",
    )
    g.add_argument(
        "--wait-subscriber",
        type=at_least(0),
        default=60.0,
        metavar="S",
        help="wait up to S s for a subscriber before publishing (0: do not wait; default: 60)",
    )


def check_ros2_options(args: argparse.Namespace, what: str) -> None:
    """Refuse a bad ``--ros2-topic`` or ``--domain-id``, and a missing extra, before any work is done."""
    from ..robot.ros2.dds import check_domain_id, cyclonedds_module, dds_topic_name

    dds_topic_name(args.ros2_topic)
    if args.domain_id is not None:
        check_domain_id(args.domain_id)
    cyclonedds_module(what)


def run_simulate_ros2(args: argparse.Namespace, values, rate_hz: float, kind: str, t=None) -> int:
    """Publish ``values`` (``(n, 3)`` samples in g or ``(n, H, W)`` frames) on ``--ros2-topic``; return the status.

    ``t``: each item's time in seconds (a frame recording's), else ``i / rate_hz``.
    """
    from ..robot.ros2.dds import DdsNode, DdsTypes, dds_type_name
    from ..robot.ros2.message_types import FLOAT_ARRAY_TYPE, IMU_TYPE, message_types
    from ..robot.ros2.messages import MessageEncoder
    from ..robot.ros2.publish import linger, publish_recording, wait_for_subscriber

    msgtype = args.ros2_type or (IMU_TYPE if kind == "sample" else FLOAT_ARRAY_TYPE)
    fields = topic_fields(args, msgtype)
    if (fields.msgtype == IMU_TYPE and fields.field is None) != (kind == "sample"):
        what = "accelerometer samples" if kind == "sample" else "frames"
        raise UsageError(f"--ros2-type {fields.msgtype} cannot carry the {what} of --data")
    if kind == "frame" and values.ndim != 3:
        raise UsageError(
            f"--ros2-topic publishes pressure maps (n, H, W), not frames of shape {values.shape[1:]}"
        )
    store = message_types(message_definitions(args), topic_type=fields.msgtype)
    encoder = MessageEncoder(fields, store, encoding=args.encoding)
    types = DdsTypes(store)
    with DdsNode(dds_options(args)) as node:
        writer = node.writer(args.ros2_topic, fields.msgtype, types)
        print(
            f"publishing {len(values)} {kind}s at {rate_hz:.4g} Hz on {args.ros2_topic} ({fields.describe()}, DDS "
            f"{dds_type_name(fields.msgtype)}, domain {node.domain_id}, {node.config_description}, qos {args.qos})",
            flush=True,
        )
        if args.wait_subscriber and not wait_for_subscriber(writer, args.wait_subscriber):
            print(
                f"tactile-torch simulate-sensor: no subscriber of {args.ros2_topic} within {args.wait_subscriber:g} s; "
                "publishing anyway",
                file=sys.stderr,
                flush=True,
            )
        n = publish_recording(writer, types, encoder, values, rate_hz=rate_hz, t=t, realtime=not args.fast)
        linger(writer, args.qos)  # the last messages arrive before the publisher leaves
    print(f"{n} messages published")
    return 0


def add_subscriber_options(g: argparse._ArgumentGroup) -> None:
    """Add the options only ``stream --ros2-topic`` has to its ROS 2 group ``g``."""
    g.add_argument(
        "--decision-topic",
        default=None,
        metavar="TOPIC",
        help="publish each decision there as std_msgs/msg/String JSON (default: TOPIC/decision; none: do not "
        "publish)",
    )
    g.add_argument(
        "--qos-depth",
        type=at_least(1, int),
        default=None,
        metavar="N",
        help="messages the reader keeps until the stream takes them (default: 1000)",
    )


def open_ros2_source(args: argparse.Namespace, spec, *, on_event, on_open):
    """Return the :class:`~tactile_torch.robot.ros2.source.Ros2Source` of ``--ros2-topic`` (the stream's source)."""
    import math

    from ..robot.ros2.messages import TopicFields
    from ..robot.ros2.source import Ros2Source

    check_ros2_options(args, "--ros2-topic")
    fields = None
    if args.ros2_type or args.field or args.sensor:
        fields = TopicFields(
            topic_fields(args, args.ros2_type).msgtype if args.ros2_type else None, args.field, args.sensor
        )
    return Ros2Source(
        args.ros2_topic,
        spec,
        fields=fields,
        msg_defs=message_definitions(args),
        dds=dds_options(args),
        silence_s=args.silence,
        idle_timeout_s=args.idle_timeout or math.inf,
        start_timeout_s=args.start_timeout or math.inf,
        reconnect=args.reconnect,
        on_event=on_event,
        on_open=on_open,
    )


def decision_topic_of(args: argparse.Namespace) -> str | None:
    """Return the topic the decisions are published on (``None``: ``--decision-topic none``)."""
    from ..robot.ros2.publish import decision_topic

    topic = args.decision_topic or decision_topic(args.ros2_topic)
    return None if topic == "none" else topic


def decision_hook(args: argparse.Namespace, source) -> list:
    """Return the output hook that publishes each result on the decision topic (none with ``none``)."""
    from ..robot.ros2.dds import DdsTypes
    from ..robot.ros2.message_types import message_types
    from ..robot.ros2.publish import DecisionPublisher
    from ..robot.stream.output import result_json

    topic = decision_topic_of(args)
    if topic is None:
        return []
    return [DecisionPublisher(source.node, topic, DdsTypes(message_types()), result_json)]


def describe_ros2_source(args: argparse.Namespace, source) -> str:
    """What the stream's ``reading`` line says it reads: the topic, its type, the DDS domain and network, the QoS."""
    from ..robot.ros2.source import message_bound

    topic = decision_topic_of(args)
    decisions = "not published" if topic is None else f"published on {topic} (std_msgs/msg/String, JSON)"
    depth, bound = source.dds.depth, message_bound(source.spec)
    queue = f"up to {depth} messages queued: {depth * bound / 2**20:.3g} MiB at most of messages up to {bound // 1024} KiB"
    qos = (
        f"qos lossless (reliable, keep all: a publisher the stream cannot keep up with is held back; {queue})"
        if args.qos == "lossless"
        else f"qos sensor (best effort; {queue}, what finds the queue full is lost, counted and said)"
    )
    return (
        f"ROS 2 topic {source.name} ({source.fields.describe()}, domain {source.domain_id}, "
        f"{source.config_description}, {qos}; decisions {decisions})"
    )


__all__ = [
    "add_dds_options",
    "add_publisher_options",
    "add_subscriber_options",
    "check_ros2_options",
    "dds_options",
    "decision_hook",
    "describe_ros2_source",
    "open_ros2_source",
    "run_simulate_ros2",
    "topic_fields",
]
