"""The candidate models of the breaking-point and claims sections, on raw input.

Each is a scikit-learn :class:`~sklearn.pipeline.Pipeline` ``features → scale → classifier``
(:func:`tactile_torch.catalogue.classifier_pipeline`) whose
``features`` step is a :class:`~sklearn.preprocessing.FunctionTransformer` around the method's
features (:func:`tactile_torch.image.exploration_features`,
:func:`tactile_torch.signal.window_features`), so that :mod:`tactile_torch.robustness` can degrade the
raw input, the features or the training split of any of them.
"""

from __future__ import annotations

import numpy as np
import torch

STUDY_FRAME_PX = 96
"""Frame side for which the study's 10-pixel erosion is kept; other frames scale it (see :func:`erosion_for`)."""


def image_features(frames, fuse: bool = True, erosion: int = 10) -> np.ndarray:
    """Method-1 features of frames ``(N, T, 3, H, W)`` as a float64 array (fused 12, or 12 per frame)."""
    from ..image import exploration_features

    return exploration_features(torch.as_tensor(frames), fuse=fuse, erosion=int(erosion)).double().numpy()


def vibration_features(windows) -> np.ndarray:
    """The 21 features of windows ``(N, 3, W)`` as a float64 array."""
    from ..signal import window_features

    return window_features(torch.as_tensor(windows)).double().numpy()


def erosion_for(frames) -> int:
    """The study's 10-pixel erosion scaled to the frame: ``round(10 min(H, W) / 96)``, at least 1."""
    return max(1, round(10 * min(frames.shape[-2:]) / STUDY_FRAME_PX))


def classifiers(random_state: int, *, svm_c: float = 10.0, svm_gamma="scale") -> dict:
    """The study's classifiers from the catalogue (:mod:`tactile_torch.catalogue`): HM-SVM, LDA, kNN
    (k = 3, city-block, inverse-distance weights, searched in a ball tree), by display name."""
    from .. import catalogue

    return {
        "HM-SVM": catalogue.make_classifier("hmsvm", random_state=random_state, C=svm_c, gamma=svm_gamma),
        "LDA": catalogue.make_classifier("lda"),
        "kNN": catalogue.make_classifier("knn"),
    }


IMAGE_SVM_C = 100.0
"""C of the method-1 HM-SVM candidates (gamma ``"scale"`` on standardised features): the middle of the
``image_classification`` section's validation grid (the study chose C and gamma on validation folds;
re-choosing them inside every fold of every level would multiply the sweeps' fits by the grid)."""


def image_candidates(random_state: int, *, erosion: int = 10, names: tuple[str, ...] | None = None) -> dict:
    """Method-1 candidates on raw frames: fused (12) features with HM-SVM (the study's model), LDA and
    kNN, and the per-frame concatenation (12 per frame) with LDA and HM-SVM."""
    from sklearn.preprocessing import FunctionTransformer

    def features(fuse: bool):
        return FunctionTransformer(image_features, kw_args={"fuse": fuse, "erosion": erosion})

    def clf():
        return classifiers(random_state, svm_c=IMAGE_SVM_C)

    from ..catalogue import classifier_pipeline

    models = {f"fused + {name}": classifier_pipeline(model, features(True)) for name, model in clf().items()}
    models["concatenated + LDA"] = classifier_pipeline(clf()["LDA"], features(False))
    models["concatenated + HM-SVM"] = classifier_pipeline(clf()["HM-SVM"], features(False))
    return {k: v for k, v in models.items() if names is None or k in names}


def vibration_candidates(random_state: int, *, names: tuple[str, ...] | None = None) -> dict:
    """Method-2 candidates on raw windows: the 21 features scaled to unit standard deviation, with the
    study's RBF SVM (C = 16, gamma = 0.0186; libsvm's one-vs-one, which the ``vibration_classification``
    section shows to be as accurate as our HM-SVM on these features and which fits many times faster),
    LDA and kNN."""
    from sklearn.preprocessing import FunctionTransformer
    from sklearn.svm import SVC

    from ..catalogue import classifier_pipeline

    clf = classifiers(random_state)
    clf["HM-SVM"] = SVC(C=16.0, gamma=0.0186)
    models = {}
    for name, model in clf.items():
        # the study's unit-std scaling, not centred
        pipe = classifier_pipeline(model, FunctionTransformer(vibration_features), scaling="unit-population")
        models[f"21 features + {'RBF SVM' if name == 'HM-SVM' else name}"] = pipe
    return {k: v for k, v in models.items() if names is None or k in names}


def serial_blas():
    """A context holding BLAS at one thread (restored on exit), for a section's many small linear-algebra
    calls: with the other core busy, two OpenBLAS threads made the SVD inside LDA's fit on 192 x 1200
    concatenated features take 6.0 s instead of 0.18 s (measured on the shared 2-core machine)."""
    from threadpoolctl import threadpool_limits

    return threadpool_limits(limits=1, user_api="blas")
