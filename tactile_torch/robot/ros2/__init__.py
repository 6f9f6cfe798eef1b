"""ROS 2 on the robot side without a ROS installation: live topics over Cyclone DDS, and bags.

Submodules: ``dds`` (Cyclone DDS participants, QoS and loopback-only configuration), ``reader`` (a
topic's messages, its losses and publishers), ``source`` (a topic as a stream source), ``publish`` (decisions published back to the robot), ``message_types`` (the
ROS 2 message types from one place: rosbags' type store, TactileState, a robot's own ``.msg``),
``messages`` (messages to values and back), ``bags`` (reading ROS 2 bags). The optional packages
(``cyclonedds``, ``rosbags``: extras ``ros2`` and ``ros``) are imported inside the functions that
need them.
"""

from ..._exports import lazy_exports

__getattr__, __dir__, __all__ = lazy_exports(
    __name__,
    {
        "source": ("Ros2Source",),
        "publish": ("DecisionPublisher", "publish_recording"),
        "dds": ("DdsOptions",),
        "reader": ("TopicReader",),
        "bags": ("read_bag",),
        "message_types": ("MessageDefinition", "message_types", "read_message_definition"),
    },
)
