"""Argument checks shared by the whole library (floor 0), and the ``random_state`` constraint.

Public functions validate once, at the entry, with these helpers (in the spirit of kornia's
``KORNIA_CHECK_SHAPE``); internal functions trust their callers. Every error names the argument, what
was expected and what was given, and is raised with its class (:mod:`tactile_torch.exceptions`).

Three modules, imported on first use so that the torch-free part stays torch-free (the robot side
uses it):

* ``_scalars`` (NumPy only): counts, numbers, positive values, random states (:func:`numpy_rng`),
  float32 saturation;
* ``_tensors`` (torch): tensors, shapes (``check_shape(x, "frames", ["B", "T", 3, "H", "W"])``),
  floating dtypes, finite values, feature matrices, torch generators;
* ``_constraints`` (scikit-learn): :data:`RANDOM_STATE`, the ``random_state`` entry of every
  estimator's ``_parameter_constraints``.

Examples
--------
>>> from tactile_torch.validation import check_count
>>> check_count(3, "step", 1)
3
"""

from .._exports import lazy_exports

__getattr__, __dir__, __all__ = lazy_exports(
    __name__,
    {
        "_scalars": (
            "FLOAT32_MAX",
            "check_count",
            "check_number",
            "check_positive",
            "numpy_rng",
            "saturate_float32",
        ),
        "_tensors": (
            "RandomState",
            "ShapeSpec",
            "as_feature_matrix",
            "check_finite",
            "check_floating",
            "check_shape",
            "check_tensor",
            "torch_generator",
        ),
        "_constraints": ("RANDOM_STATE",),
    },
)
