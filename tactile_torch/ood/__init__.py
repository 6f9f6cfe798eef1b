"""The out-of-distribution score of exported classifiers: a class-conditional Mahalanobis distance of a
sample's features to the training data, with its threshold ("unknown" beyond it).

The estimator and its torch modules are ``_mahalanobis``'s; the ONNX branch that adds the score to a
bundle is :mod:`tactile_torch.export.ood_branch`'s, and the generator of signals no surface gives is
:mod:`tactile_torch.data.out_of_distribution`'s.
"""

from .._exports import lazy_exports

__getattr__, __dir__, __all__ = lazy_exports(
    __name__,
    {
        "_mahalanobis": (
            "DEFAULT_QUANTILE",
            "DistanceHead",
            "LOG_FLOOR_QUANTILE",
            "MahalanobisDistance",
            "MahalanobisNovelty",
            "OOD_ARRAYS",
            "WithDistance",
            "distance_module",
            "fit_ood",
            "fit_rule",
            "log_floor",
            "ood_distance",
            "signed_log",
        ),
    },
)
