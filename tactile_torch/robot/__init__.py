"""The robot side: everything an exported bundle needs on the robot's computer, importable without torch.

Every module of this package imports only the standard library, numpy, and (inside the functions that
need them) onnxruntime, pyserial, and the optional ``cyclonedds`` and ``rosbags`` (ROS 2 topics and bags,
extras ``ros2`` and ``ros``): the runtime install (``pip install tactile-torch``) runs it, and
``tests/robot/test_package.py`` fails if any of its modules imports torch, scikit-learn, scipy or numba,
or loads an optional package at import time.
The training side (:mod:`tactile_torch.training`, the exporters) imports from here, never the other way.

The package's API is declared the project's one way (:func:`tactile_torch._exports.lazy_exports`, standard
library only); the file-level names (contract constants, readers' option types) are imported from their module.
"""

from .._exports import lazy_exports

__getattr__, __dir__, __all__ = lazy_exports(
    __name__,
    {
        "runtime": ("NonFiniteScoresError", "OnnxPipeline", "Prediction", "beyond_range", "sensor_range_g"),
        "stream": ("Window", "WindowReader"),
        "stream_source": ("ArraySource", "Break", "ItemSpec", "Reading", "Source", "SourceCounts"),
        "serial_source": ("SerialSource",),
        "stream_segments": ("Segments", "Sequencer", "SlidingWindows", "TouchSegment", "TouchSegmenter"),
        "touches": ("TouchLevels", "fit_frames", "touch_levels"),
        "early_decision": ("EarlyRule", "calibrate_early_rule"),
        "live": ("LiveOptions", "LiveStream", "item_spec"),
        "stream_output": (
            "classify_segments",
            "classify_touches",
            "classify_windows",
            "result_json",
            "result_record",
            "result_text",
        ),
        "discovery": ("SurfaceDiscovery", "stream_consumer"),
        "model_file": ("ModelFile", "load_model_file", "save_model_file"),
        "formats": ("read_data", "read_explorations", "read_features", "read_recordings"),
        "data_sources": ("DataOptions", "read_source"),
        "errors": ("InputError", "InputTypeError", "InputValueError", "InternalError", "internal_stage"),
    },
)
