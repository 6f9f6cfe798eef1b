"""Feature steps: scikit-learn transformers from a raw input (windows, frames, pressure maps, feature
files) to a feature matrix, each with its torch graph (``to_module()``), and the features of a data file.

``transformers`` holds the transformers (the ops themselves live in :mod:`tactile_torch.image` and
:mod:`tactile_torch.signal`); ``files`` reads a data file's features (:func:`load_features`, a
:class:`FeatureSet`), as ``tactile-torch train`` does.
"""

from .._exports import lazy_exports

__getattr__, __dir__, __all__ = lazy_exports(
    __name__,
    {
        "transformers": (
            "FeaturePassthrough",
            "ImageFeatureTransformer",
            "PressureImageFeatures",
            "RankedFeatureSelector",
            "RawInput",
            "TaxelFeatureTransformer",
            "WindowFeatureTransformer",
        ),
        "files": ("FRAME_FEATURES", "FeatureSet", "frame_features", "load_features"),
    },
)
