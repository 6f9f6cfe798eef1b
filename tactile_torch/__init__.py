"""tactile-torch: recognise the surface a robot touches.

Two published methods as batched torch ops: tactile-image fusion with a hierarchical SVM
(:mod:`tactile_torch.image`, :mod:`tactile_torch.svm`) and vibration features with an SVM and a
Pitman-Yor process mixture (:mod:`tactile_torch.signal`, :mod:`tactile_torch.mixture`).

This top-level module imports nothing heavy on purpose: :mod:`tactile_torch.robot.runtime` must load on a
robot where torch is not installed.
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("tactile-torch")
except PackageNotFoundError:  # running from a source tree that was not installed
    __version__ = "0.0.0+unknown"

__all__ = ["__version__"]
