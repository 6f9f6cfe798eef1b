"""A ROS 2 publisher process for the tests: a recording, with pauses and departures, over loopback DDS.

Run as ``python -m tests.ros2_publisher``; a real DDS participant in its own process (the library's
:func:`tactile_torch.robot.ros2.publish.publish_recording`), on the loopback configuration:

    python -m tests.ros2_publisher --domain-id 17 --topic /hand/tactile --type tactile_msgs/msg/TactileState \\
        --sensor index --values frames.npy --rate 100 --plan 0:20,pause=0.8,20:40,leave=1.0,40:60

``--plan``: ``a:b`` publishes items ``a`` to ``b - 1`` at the rate (stamped on the recording's clock:
item ``i`` at ``i / rate`` after the first, whatever the pauses); ``pause=S`` stops for S seconds (the
writer stays); ``leave=S`` deletes the participant (subscribers see the publisher leave), waits S
seconds and comes back as a new participant. Before each part it waits for a subscriber. Prints
``ready`` once the first subscriber matched and ``done N`` at the end.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from tactile_torch.robot.ros2.dds import DdsNode, DdsOptions, DdsTypes
from tactile_torch.robot.ros2.message_types import message_types
from tactile_torch.robot.ros2.messages import MessageEncoder, TopicFields
from tactile_torch.robot.ros2.publish import linger, publish_recording, wait_for_subscriber


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m tests.ros2_publisher")
    p.add_argument("--domain-id", type=int, required=True)
    p.add_argument("--topic", required=True)
    p.add_argument("--type", required=True)
    p.add_argument("--sensor", default=None)
    p.add_argument("--encoding", default="32FC1")
    p.add_argument("--values", required=True, help=".npy of (n, 3) samples in g or (n, H, W) frames")
    p.add_argument("--rate", type=float, required=True)
    p.add_argument("--plan", default=None, help="a:b,pause=S,leave=S,... (default: everything)")
    p.add_argument("--qos", default="sensor")
    p.add_argument("--config", default="loopback")
    p.add_argument("--wait-subscriber", type=float, default=60.0)
    p.add_argument("--delay", type=float, default=0.0, help="seconds to wait before the participant starts")
    args = p.parse_args(argv)
    values = np.load(args.values)
    plan = (args.plan or f"0:{len(values)}").split(",")
    store = message_types()
    fields = TopicFields(args.type, sensor=args.sensor)
    encoder = MessageEncoder(fields, store, encoding=args.encoding)
    types = DdsTypes(store)
    options = DdsOptions(domain_id=args.domain_id, config=args.config, qos=args.qos)
    time.sleep(args.delay)
    stamp0 = time.time_ns()
    node = DdsNode(options)
    writer = node.writer(args.topic, args.type, types)
    written, ready = 0, False
    try:
        for step in plan:
            if step.startswith("pause="):
                time.sleep(float(step.split("=")[1]))
            elif step.startswith("leave="):
                linger(writer, args.qos)
                node.close()
                time.sleep(float(step.split("=")[1]))
                node = DdsNode(options)
                writer = node.writer(args.topic, args.type, types)
            else:
                if not wait_for_subscriber(writer, args.wait_subscriber):
                    print("no subscriber", flush=True)
                    return 3
                if not ready:
                    print("ready", flush=True)
                    ready = True
                start, stop = (int(v) for v in step.split(":"))
                written += publish_recording(
                    writer,
                    types,
                    encoder,
                    values,
                    rate_hz=args.rate,
                    start=start,
                    stop=stop,
                    stamp0_ns=stamp0,
                )
        linger(writer, args.qos)  # the last messages arrive before the participant goes
    finally:
        node.close()
    print(f"done {written}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
