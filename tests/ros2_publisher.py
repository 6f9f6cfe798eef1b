"""A ROS 2 publisher process for the tests: a recording, with pauses and departures, over loopback DDS.

Run as ``python -m tests.ros2_publisher``; a real DDS participant in its own process (the library's
:func:`tactile_torch.robot.ros2.publish.publish_recording`), on the loopback configuration:

    python -m tests.ros2_publisher --domain-id 17 --topic /hand/tactile --type tactile_msgs/msg/TactileState \\
        --sensor index --values frames.npy --rate 100 --plan 0:20,pause=0.8,20:40,leave=1.0,40:60

``--plan``: ``a:b`` publishes items ``a`` to ``b - 1`` at the rate (stamped on the sensor's clock: item
``i`` at ``i / rate`` after the first, plus the pauses before it); ``pause=S`` stops for S seconds (the
writer stays; the sensor's clock runs on, as a real sensor's does when it pauses); ``stall=S`` stops
for S seconds and then writes what it owes at once, stamped on schedule (a publisher starved of CPU:
the sensor did not pause); ``leave=S`` deletes the participant (subscribers see the publisher leave),
waits S seconds and comes back as a new participant (stamps go on from where they were: nothing was
sent meanwhile); ``crash`` kills the process (SIGKILL: subscribers see it leave when its DDS lease
ends). ``--sensors a,b,c`` publishes ``TactileState`` messages of several sensors (``--values`` then
holds ``(n, k, H, W)``). Before each part it waits for a subscriber. Prints
``ready`` once the first subscriber matched and ``done N`` at the end.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from tactile_torch.robot.ros2.dds import DdsNode, DdsOptions, DdsTypes
from tactile_torch.robot.ros2.message_types import message_types
from tactile_torch.robot.ros2.messages import MessageEncoder, TopicFields, encode_sensors
from tactile_torch.robot.ros2.publish import linger, publish_recording, wait_for_subscriber


class _HandEncoder:
    """Encode ``(k, H, W)`` frames as one ``TactileState`` of ``k`` named sensors (publish_recording's encoder)."""

    def __init__(self, store, names):
        self.store, self.names = store, names
        self.fields = TopicFields("tactile_msgs/msg/TactileState")

    def encode(self, values, stamp_ns=0):
        return encode_sensors(self.store, list(zip(self.names, values, strict=True)), stamp_ns)


def main(argv: list[str] | None = None) -> int:  # noqa: PLR0915
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
    p.add_argument("--sensors", default=None, help="names of the sensors of a TactileState of several")
    p.add_argument(
        "--fast", action="store_true", help="write as fast as the writer takes them, stamped at --rate"
    )
    args = p.parse_args(argv)
    values = np.load(args.values)
    plan = (args.plan or f"0:{len(values)}").split(",")
    store = message_types()
    if args.sensors:  # a hand: one TactileState of every sensor per message
        encoder = _HandEncoder(store, args.sensors.split(","))
    else:
        encoder = MessageEncoder(TopicFields(args.type, sensor=args.sensor), store, encoding=args.encoding)
    types = DdsTypes(store)
    options = DdsOptions(domain_id=args.domain_id, config=args.config, qos=args.qos)
    time.sleep(args.delay)
    stamp0 = time.time_ns()
    node = DdsNode(options)
    writer = node.writer(args.topic, args.type, types)
    written, ready, owed_at_once = 0, False, 0
    try:
        for step in plan:
            if step.startswith("pause="):
                pause = float(step.split("=")[1])
                time.sleep(pause)
                stamp0 += round(pause * 1e9)
            elif step.startswith("stall="):
                stall = float(step.split("=")[1])
                time.sleep(
                    stall
                )  # starved of CPU: what the sensor gave meanwhile is written at once, on schedule
                owed_at_once = round(stall * args.rate)
            elif step == "crash":
                import os
                import signal

                print(f"crash {written}", flush=True)
                os.kill(os.getpid(), signal.SIGKILL)
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
                if owed_at_once:
                    owed = min(start + owed_at_once, stop)
                    written += publish_recording(
                        writer, types, encoder, values, rate_hz=args.rate, start=start, stop=owed,
                        stamp0_ns=stamp0, realtime=False,
                    )  # fmt: skip
                    start, owed_at_once = owed, 0
                written += publish_recording(
                    writer,
                    types,
                    encoder,
                    values,
                    rate_hz=args.rate,
                    start=start,
                    stop=stop,
                    stamp0_ns=stamp0,
                    realtime=not args.fast,
                )
        linger(writer, args.qos)  # the last messages arrive before the participant goes
    finally:
        node.close()
    print(f"done {written}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
