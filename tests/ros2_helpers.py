"""Test helpers for ROS 2: a free DDS domain per test, loopback-only configurations, a decision listener, bags.

Network rule: every DDS participant the tests start (in the test process or in a subprocess) uses the
loopback configuration the library ships (:func:`tactile_torch.robot.ros2.dds.loopback_config`), given
explicitly; :func:`ros2_env` also removes ``CYCLONEDDS_URI`` and ``ROS_DOMAIN_ID`` from a subprocess's
environment, so that a developer's own settings cannot send test traffic anywhere else.

:func:`free_domain_id` gives each test a DDS domain no other process on this machine is using (no UDP
port of the domain's range bound), starting from one derived from the process id: tests of several
engineers running at once on the machine never share a domain, so their messages never cross.
"""

from __future__ import annotations

import json
import os
import re
import sys
import time
from pathlib import Path

from tactile_torch.robot.ros2.dds import MAX_DOMAIN_ID, loopback_config

_PORT_BASE, _DOMAIN_GAIN = 7400, 250  # RTPS port mapping: a domain d uses ports 7400 + 250 d + [0, 250)
_taken: set[int] = set()


def _bound_udp_ports() -> set[int]:
    ports = set()
    for table in ("/proc/net/udp", "/proc/net/udp6"):
        try:
            lines = Path(table).read_text().splitlines()[1:]
        except OSError:
            continue
        for line in lines:
            local = line.split()[1]
            ports.add(int(local.rsplit(":", 1)[1], 16))
    return ports


def free_domain_id() -> int:
    """Return a DDS domain id that no process on this machine uses now (and this run has not used)."""
    bound = _bound_udp_ports()
    first = 1 + os.getpid() % MAX_DOMAIN_ID
    for k in range(MAX_DOMAIN_ID):
        domain = 1 + (first + k) % MAX_DOMAIN_ID  # 1..232: domain 0 is every ROS 2 system's default
        low = _PORT_BASE + _DOMAIN_GAIN * domain
        if domain in _taken or any(low <= p < low + _DOMAIN_GAIN for p in bound):
            continue
        _taken.add(domain)
        return domain
    raise RuntimeError("no free DDS domain id on this machine")


def ros2_env(**extra: str) -> dict[str, str]:
    """Return the environment for a subprocess: this one without CYCLONEDDS_URI and ROS_DOMAIN_ID, plus ``extra``."""
    env = {k: v for k, v in os.environ.items() if k not in ("CYCLONEDDS_URI", "ROS_DOMAIN_ID")}
    env.update(extra)
    return env


def traced_loopback(path: Path, verbosity: str = "finest") -> Path:
    """Write the loopback configuration with Cyclone's trace at ``verbosity`` to ``path`` (trace: ``path.log``)."""
    xml = loopback_config().replace(
        "</Domain>",
        f"<Tracing><Verbosity>{verbosity}</Verbosity><OutputFile>{path.with_suffix('.log')}</OutputFile></Tracing></Domain>",
    )
    path.write_text(xml)
    return path


def sent_to(trace: Path) -> list[str]:
    """Return the destination address of every RTPS message a traced participant sent (``finest`` trace)."""
    text = trace.read_text()
    return re.findall(r"ddsi_xpack_send .*\[ (?:udp|udp6)/([^ \]]+?):\d+@\d+", text)


def selected_interfaces(trace: Path) -> str:
    """Return the ``selected interfaces:`` line of a traced participant."""
    match = re.search(r"selected interfaces: (.*)", trace.read_text())
    return match[1] if match else ""


class DecisionListener:
    """A DDS participant in the test process that collects the JSON decisions published on a topic."""

    def __init__(self, topic: str, domain_id: int, *, config: str = "loopback") -> None:
        from tactile_torch.robot.ros2.dds import DdsNode, DdsOptions, DdsTypes
        from tactile_torch.robot.ros2.message_types import STRING_TYPE, message_types
        from tactile_torch.robot.ros2.reader import TopicReader

        self.store = message_types()
        self.node = DdsNode(DdsOptions(domain_id=domain_id, config=config, qos="lossless"))
        self.reader = TopicReader(self.node, topic, STRING_TYPE, DdsTypes(self.store))
        self.decisions: list[dict] = []

    def poll(self, timeout_s: float = 0.1) -> list[dict]:
        for received in self.reader.take(timeout_s):
            message = self.store.deserialize_cdr(received.cdr, "std_msgs/msg/String")
            self.decisions.append(json.loads(message.data))
        return self.decisions

    def wait_for(self, n: int, timeout_s: float = 20.0) -> list[dict]:
        """Collect until ``n`` decisions arrived or ``timeout_s`` passed; return them all."""
        deadline = time.monotonic() + timeout_s
        while len(self.decisions) < n and time.monotonic() < deadline:
            self.poll(0.1)
        return self.decisions

    def close(self) -> None:
        self.node.close()


def write_frame_bag(
    path, fields, frames, *, storage="mcap", topic="/tactile", encoding="32FC1", stamps_ns=None, store=None
):
    """A rosbag2 of one frame per message, written with the same encoder simulate-sensor publishes with."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    from tactile_torch.robot.ros2.message_types import message_types
    from tactile_torch.robot.ros2.messages import MessageEncoder

    store = store or message_types()
    encoder = MessageEncoder(fields, store, encoding=encoding)
    plugin = StoragePlugin.SQLITE3 if storage == "sqlite3" else StoragePlugin.MCAP
    with Writer(path, version=9, storage_plugin=plugin) as writer:
        conn = writer.add_connection(topic, fields.msgtype, typestore=store)
        for i, frame in enumerate(frames):
            stamp = 2 * 10**9 + i * 66_000_000 if stamps_ns is None else stamps_ns[i]
            writer.write(conn, 10**9 + i * 10**7, encoder.encode(frame, stamp))
    return path


def start_publisher(tmp_path, values, rate, topic, domain, msgtype, *extra):
    """Start ``python -m tests.ros2_publisher`` publishing ``values`` (saved in ``tmp_path``); return the process."""
    import subprocess

    import numpy as np

    path = Path(tmp_path) / f"values-{domain}.npy"
    np.save(path, values)
    argv = [
        sys.executable, "-m", "tests.ros2_publisher", "--domain-id", str(domain), "--topic", topic,
        "--type", msgtype, "--values", str(path), "--rate", str(rate), *extra,
    ]  # fmt: skip
    return subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=ros2_env())


def cli(*args: str) -> list[str]:
    """The command line of ``tactile-torch`` with ``args``, run by this interpreter."""
    return [sys.executable, "-m", "tactile_torch.cli", *args]
