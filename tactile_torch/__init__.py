"""tactile-torch: recognise the surface a robot touches.

Two published methods as batched torch ops: tactile-image fusion with a hierarchical SVM
(:mod:`tactile_torch.image`, :mod:`tactile_torch.svm`) and vibration features with an SVM and a
Pitman-Yor process mixture (:mod:`tactile_torch.signal`, :mod:`tactile_torch.mixture`).

This top-level module imports nothing heavy on purpose: :mod:`tactile_torch.robot.runtime` must load on a
robot where torch is not installed.
"""

from importlib.metadata import PackageNotFoundError, version

from ._exports import lazy_exports

try:
    __version__ = version("tactile-torch")
except PackageNotFoundError:  # running from a source tree that was not installed
    __version__ = "0.0.0+unknown"

# The top level exports only the version: every public name lives in the module or package of its
# concern (``from tactile_torch.svm import SVC``), so that importing the top level costs nothing.
__getattr__, __dir__, __all__ = lazy_exports(__name__, {}, defined=("__version__",))
