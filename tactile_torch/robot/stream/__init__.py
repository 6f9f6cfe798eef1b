"""The live stream on the robot side (NumPy and pyserial only): sources, windows, touches and decisions.

A stream is assembled from stages (:mod:`tactile_torch.robot.stream.source` describes them): a
source (``serial_source`` over ``port_lines`` and the ``wire`` protocol, or a ROS 2 topic,
:mod:`tactile_torch.robot.ros2`), the ``segments`` (sequencing, gaps, sliding windows, touches:
``touches``, ``windows``), the ``early_decision`` rule, and the ``output`` (one decision per window or
touch, as text or JSON); ``live`` assembles them, for every source and bundle (:class:`LiveStream`:
the one assembly), and ``discovery`` finds new surfaces in a stream. ``sequencer`` judges the
sensor's time stamps (losses, stamps off schedule, another rate).
"""

from ..._exports import lazy_exports

__getattr__, __dir__, __all__ = lazy_exports(
    __name__,
    {
        "source": ("ArraySource", "Break", "ItemSpec", "Reading", "Source", "SourceCounts"),
        "serial_source": ("SerialSource", "TIME_UNITS"),
        "sequencer": ("Sequencer",),
        "segments": (
            "GAP_TOLERANCE",
            "RATE_TOLERANCE",
            "Segments",
            "SlidingWindows",
            "Window",
        ),
        "touch_segments": ("TouchSegment", "TouchSegmenter"),
        "touches": ("TouchLevels", "fit_frames", "touch_levels"),
        "early_decision": ("EarlyRule", "calibrate_early_rule"),
        "live": ("LiveOptions", "LiveStream", "item_spec"),
        "output": (
            "classify_segments",
            "classify_windows",
            "result_json",
            "result_record",
            "result_text",
        ),
        "touch_output": ("TouchResult", "classify_touches"),
        "discovery": ("SurfaceDiscovery", "stream_consumer"),
        "port_lines": ("StreamDisconnected", "StreamEvent", "StreamTimeout", "open_serial_port"),
        "wire": ("format_sample", "parse_line", "parse_sample", "pseudo_terminal", "simulate_sensor"),
    },
)
