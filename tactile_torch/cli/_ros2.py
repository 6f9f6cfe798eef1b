"""The ROS 2 options of ``stream`` and ``simulate-sensor``, and ``simulate-sensor --ros2-topic``.

Torch-free: the robot runs them with ``cyclonedds`` and ``rosbags`` (the extra ``ros2``), imported inside
the functions. DDS stays on this machine's loopback unless ``--dds-config`` or ``CYCLONEDDS_URI`` says
otherwise (:func:`tactile_torch.robot.ros2_dds.resolve_config`).
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
        + ("to read (default: the only one)" if reader else "to publish (default: tactile)"),
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
        choices=["sensor", "reliable"],
        help="reliability: sensor (best effort, ROS 2's sensor-data profile) or reliable (default: sensor)",
    )
    return g


def dds_options(args: argparse.Namespace):
    """Return the :class:`~tactile_torch.robot.ros2_dds.DdsOptions` the parsed arguments declare."""
    from ..robot.ros2_dds import DEFAULT_DEPTH, DdsOptions

    return DdsOptions(
        domain_id=args.domain_id,
        config=args.dds_config,
        qos=args.qos,
        depth=getattr(args, "qos_depth", None) or DEFAULT_DEPTH,
    )


def topic_fields(args: argparse.Namespace, msgtype: str):
    """Return the :class:`~tactile_torch.robot.ros_messages.TopicFields` of ``msgtype`` and the options."""
    from ..robot.ros_messages import TopicFields, ros_type_name

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


def run_simulate_ros2(args: argparse.Namespace, values, rate_hz: float, kind: str) -> int:
    """Publish ``values`` (``(n, 3)`` samples in g or ``(n, H, W)`` frames) on ``--ros2-topic``; return the status."""
    from ..robot.ros2_dds import DdsNode, DdsTypes, dds_type_name
    from ..robot.ros2_publish import linger, publish_recording, wait_for_subscriber
    from ..robot.ros_messages import FLOAT_ARRAY_TYPE, IMU_TYPE, MessageEncoder, message_types

    msgtype = args.ros2_type or (IMU_TYPE if kind == "sample" else FLOAT_ARRAY_TYPE)
    fields = topic_fields(args, msgtype)
    if (fields.msgtype == IMU_TYPE and fields.field is None) != (kind == "sample"):
        what = "accelerometer samples" if kind == "sample" else "frames"
        raise UsageError(f"--ros2-type {fields.msgtype} cannot carry the {what} of --data")
    store = message_types(message_definitions(args), topic_type=fields.msgtype)
    encoder = MessageEncoder(fields, store, encoding=args.encoding)
    types = DdsTypes(store)
    with DdsNode(dds_options(args)) as node:
        writer = node.writer(args.ros2_topic, fields.msgtype, types)
        print(
            f"publishing {len(values)} {kind}s at {rate_hz:g} Hz on {args.ros2_topic} ({fields.describe()}, DDS "
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
        n = publish_recording(writer, types, encoder, values, rate_hz=rate_hz, realtime=not args.fast)
        linger(writer, args.qos)
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


def run_stream_ros2(args: argparse.Namespace, stopped: type[BaseException]) -> int:
    """Classify the items of ``--ros2-topic`` until the stream ends; return the exit status.

    ``stopped``: the exception SIGTERM raises (the command's), reported as a requested end.
    """
    import math

    from ..robot.live import LiveOptions, LiveStream, item_spec
    from ..robot.port_lines import StreamDisconnected, StreamTimeout
    from ..robot.ros2_dds import DdsNode, DdsTypes, cyclonedds_module
    from ..robot.ros2_publish import DecisionPublisher, decision_topic
    from ..robot.ros2_source import Ros2Source
    from ..robot.ros_messages import message_types
    from ..robot.runtime import OnnxPipeline
    from ..robot.stream_output import result_json, result_text
    from . import STREAM_DISCONNECTED_EXIT, STREAM_NO_DATA_EXIT, STREAM_STOPPED_EXIT
    from ._options import parse_range_g

    cyclonedds_module("stream --ros2-topic")
    range_g = parse_range_g(args.range, "--range", off=True)
    pipe = OnnxPipeline(args.model, intra_op_threads=args.threads)
    spec = item_spec(pipe, range_g=range_g)
    options = LiveOptions(
        step=args.step, max_results=args.max_windows or None, vote=args.vote, vote_method=args.vote_method
    )
    fields = topic_fields(args, args.ros2_type) if args.ros2_type else None
    if fields is None and (args.field or args.sensor):
        from ..robot.ros_messages import TopicFields

        fields = TopicFields(None, args.field, args.sensor)
    info = sys.stderr if args.json else sys.stdout  # --json: stdout holds nothing but the JSON lines

    def say(message: str) -> None:
        print(f"tactile-torch stream: {message}", file=sys.stderr, flush=True)

    publish = args.decision_topic or decision_topic(args.ros2_topic)
    with DdsNode(dds_options(args)) as node:

        def opened(name: str) -> None:
            src = live.source
            target = (
                "not published"
                if publish == "none"
                else f"published on {publish} (std_msgs/msg/String, JSON)"
            )
            print(
                f"{pipe!r}: reading ROS 2 topic {name} ({src.fields.describe()}, domain {node.domain_id}, "
                f"{node.config_description}, qos {args.qos}); {live.segment} of {live.size} {spec.kind}s; decisions "
                f"{target}",
                file=info,
                flush=True,
            )

        source = Ros2Source(
            args.ros2_topic,
            spec,
            fields=fields,
            msg_defs=message_definitions(args),
            dds=dds_options(args),
            silence_s=args.silence,
            idle_timeout_s=args.idle_timeout or math.inf,
            start_timeout_s=args.start_timeout or math.inf,
            reconnect=args.reconnect,
            on_event=lambda event: say(event.message),
            on_open=opened,
            node=node,
        )
        live = LiveStream(pipe, source, options, on_event=lambda event: say(event.message))
        write = result_json if args.json else result_text
        outputs = [lambda result: print(write(result), flush=True)]
        publisher = None
        if publish != "none":
            publisher = DecisionPublisher(node, publish, DdsTypes(message_types()), result_json)
            outputs.append(publisher)
        live.warm_up()  # the first inference allocates: before the reader exists
        status = 0
        try:
            for result in live:
                for output in outputs:
                    output(result)
        except StreamTimeout as err:
            say(str(err))
            status = STREAM_NO_DATA_EXIT
        except StreamDisconnected as err:
            say(str(err))
            status = STREAM_DISCONNECTED_EXIT
        except (KeyboardInterrupt, stopped) as err:
            say(f"stopped by {'SIGINT (Ctrl-C)' if isinstance(err, KeyboardInterrupt) else 'SIGTERM'}")
            status = STREAM_STOPPED_EXIT
        for result in live.finish():
            for output in outputs:
                output(result)
        published = "" if publisher is None else f", {publisher.published} decisions published on {publish}"
        print(live.summary() + published, file=info, flush=True)
    return status


__all__ = [
    "add_dds_options",
    "add_publisher_options",
    "add_subscriber_options",
    "dds_options",
    "run_simulate_ros2",
    "run_stream_ros2",
    "topic_fields",
]
