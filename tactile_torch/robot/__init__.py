"""The robot side: everything an exported bundle needs on the robot's computer, importable without torch.

Every module of this package imports only the standard library, numpy, the library's floor-0 modules
(:mod:`tactile_torch.exceptions`, the torch-free checks of :mod:`tactile_torch.validation`), and (inside
the functions that need them) onnxruntime, pyserial, and the optional ``cyclonedds`` and ``rosbags``
(ROS 2 topics and bags, extras ``ros2`` and ``ros``): the runtime install (``pip install tactile-torch``)
runs it, and ``tests/robot/test_package.py`` fails if any of its modules imports torch, scikit-learn,
scipy or numba, or loads an optional package at import time.
The training side (:mod:`tactile_torch.training`, the exporters) imports from here, never the other way.

Sub-packages by concern: :mod:`tactile_torch.robot.files` (data and model files),
:mod:`tactile_torch.robot.stream` (the live stream: sources, windows, touches, decisions),
:mod:`tactile_torch.robot.ros2` (ROS 2 topics and bags); beside them ``runtime`` (:class:`OnnxPipeline`),
``contract`` (the ONNX names) and ``integrity`` (the bundles' digest).

The package's API is declared the project's one way (:func:`tactile_torch._exports.lazy_exports`, standard
library only); the file-level names (contract constants, readers' option types) are imported from their module.
"""

from .._exports import lazy_exports

__getattr__, __dir__, __all__ = lazy_exports(
    __name__,
    {
        "runtime": ("NonFiniteScoresError", "OnnxPipeline", "Prediction", "beyond_range", "sensor_range_g"),
    },
)
