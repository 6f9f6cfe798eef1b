"""The robot side: everything an exported bundle needs on the robot's computer, importable without torch.

Every module of this package imports only the standard library, numpy, and (inside the functions that
need them) onnxruntime and pyserial: the runtime install (``pip install tactile-torch``) runs it, and
``tests/test_robot_package.py`` fails if any of its modules imports torch, scikit-learn, scipy or numba.
The training side (:mod:`tactile_torch.training`, the exporters) imports from here, never the other way.
"""

from .._exports import lazy_exports

# The robot side's public API is its modules (``from tactile_torch.robot.runtime import OnnxPipeline``).
__getattr__, __dir__, __all__ = lazy_exports(
    __name__,
    {},
    submodules=(
        "checks",
        "contract",
        "csv_logs",
        "data_sources",
        "discovery",
        "formats",
        "model_file",
        "npz",
        "port_lines",
        "ros_bags",
        "runtime",
        "safe_write",
        "stream",
        "stream_output",
        "windows",
        "wire",
    ),
)
