"""The ROS 2 publisher of the stream benchmark: frames out, and the time until each reply comes back.

Run as its own process by :mod:`bench.ros2_rows` (``python -m bench.ros2_probe publish ...``), on the
loopback-only DDS configuration and a DDS domain of its own:

- ``publish``: writes the frames of a ``.npy`` ``(n, H, W)`` as ``std_msgs/msg/Float32MultiArray``
  messages on ``--topic`` (as fast as the writer takes them, or paced at ``--rate``), after a subscriber
  matched; subscribes to ``--replies`` (``std_msgs/msg/String`` JSON) and, for each reply, takes the
  time from writing the frame it answers to its arrival, on this process's clock. A reply answers frame
  ``i`` (the echo's ``{"i": i}``), or a touch that the frame ``start + frames`` ended (the stream's
  decision JSON: the first frame below the release level). Prints one JSON object at the end:
  ``{"written": n, "seconds": s, "replies": [[i, ms], ...]}``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np

from tactile_torch.robot.ros2.dds import DdsNode, DdsOptions, DdsTypes
from tactile_torch.robot.ros2.message_types import FLOAT_ARRAY_TYPE, STRING_TYPE, message_types
from tactile_torch.robot.ros2.messages import MessageEncoder, TopicFields
from tactile_torch.robot.ros2.publish import linger, wait_for_subscriber
from tactile_torch.robot.ros2.reader import TopicReader


def _reply_index(reply: dict) -> int | None:
    if "i" in reply:
        return int(reply["i"])
    if reply.get("event") == "touch" and reply.get("ended_by") == "release":
        return int(reply["start"]) + int(reply["frames"])
    return None


def publish(args) -> int:
    frames = np.load(args.values)
    store = message_types()
    types = DdsTypes(store)
    encoder = MessageEncoder(TopicFields(FLOAT_ARRAY_TYPE), store)
    with DdsNode(DdsOptions(domain_id=args.domain_id, config="loopback", qos=args.qos)) as node:
        replies = TopicReader(node, args.replies, STRING_TYPE, types, profile="reliable")
        writer = node.writer(args.topic, FLOAT_ARRAY_TYPE, types)
        if not wait_for_subscriber(writer, 60.0):
            print(json.dumps({"error": "no subscriber"}))
            return 3
        written_at = np.full(len(frames), np.nan)
        arrived: list[tuple[int, float]] = []

        def collect(timeout: float) -> None:
            for m in replies.take(timeout):
                now = time.monotonic()
                i = _reply_index(json.loads(store.deserialize_cdr(m.cdr, STRING_TYPE).data))
                if i is not None and 0 <= i < len(frames):
                    arrived.append((i, now))

        cdrs = [encoder.encode(f) for f in frames]  # encoded beforehand: the writer is timed, not the encoder
        began = time.monotonic()
        for i, cdr in enumerate(cdrs):
            if args.rate:
                wait = began + i / args.rate - time.monotonic()
                if wait > 0:
                    collect(wait)  # replies are taken while waiting for the next frame's time
            written_at[i] = time.monotonic()
            writer.write(types.sample(FLOAT_ARRAY_TYPE, cdr))
        seconds = time.monotonic() - began
        linger(writer, args.qos)
        deadline = time.monotonic() + 3.0
        while time.monotonic() < deadline:
            collect(0.1)
    latencies = [[i, round((t - written_at[i]) * 1e3, 4)] for i, t in arrived]
    print(json.dumps({"written": len(frames), "seconds": seconds, "replies": latencies}))
    return 0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m bench.ros2_probe")
    p.add_argument("role", choices=["publish"])
    p.add_argument("--domain-id", type=int, required=True)
    p.add_argument("--topic", default="/bench/frames")
    p.add_argument("--replies", default="/bench/replies")
    p.add_argument("--values", help="publish: .npy of (n, H, W) frames")
    p.add_argument(
        "--rate", type=float, default=0.0, help="publish: frames per second (0: as fast as possible)"
    )
    p.add_argument("--qos", default="sensor")
    args = p.parse_args(argv)
    return publish(args)


if __name__ == "__main__":
    sys.exit(main())
