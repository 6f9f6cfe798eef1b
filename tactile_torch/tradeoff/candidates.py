"""The candidate models of a trade-off study: classifiers x feature sets, each a scikit-learn ``Pipeline``.

Every candidate is ``Pipeline([("features", <raw input → features>), ("select", <k best>)?,
("scale", StandardScaler()), ("classifier", <classifier>)])``: it takes the data file's raw input,
so it can be cross-validated, exported whole and swept over input degradations (``sklearn.base.clone``
gives an unfitted copy).

Classifiers (:data:`CLASSIFIERS`), at fixed hyper-parameters (the study compares model families, not
tuning; a grid search per candidate would multiply the cost):

* ``HM-SVM``: :class:`~tactile_torch.svm.HierarchicalSVC`, RBF, ``C = 16`` (the vibration study's),
  ``gamma = 1 / n_features`` (scikit-learn's ``"scale"`` on standardised features);
* ``SVC``: :class:`~tactile_torch.svm.SVC`, the same kernel and parameters;
* ``LDA``: scikit-learn's ``LinearDiscriminantAnalysis``;
* ``kNN``: ``KNeighborsClassifier(n_neighbors=3, metric="cityblock", weights="distance")`` (the study's);
* ``NCM``: nearest class mean, scikit-learn's ``NearestCentroid`` (Euclidean), the simplest baseline.

Feature sets by input kind (:func:`feature_sets`): vibration: the 21 features at every allowed window
size and the ``k`` best-ranked of the 21 at the reference window; RGB explorations: fused 12,
per-frame ``T x 12`` and, for frames of at most :data:`~.transformers.MAX_TAXELS` pixels, per-taxel
time series; raw pressure maps: the same three through :class:`~.transformers.PressureImageFeatures`;
a feature file: all columns and the ``k`` best-ranked.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

from sklearn.pipeline import Pipeline
from sklearn.preprocessing import StandardScaler

from .transformers import (
    MAX_TAXELS,
    FeaturePassthrough,
    ImageFeatureTransformer,
    PressureImageFeatures,
    RankedFeatureSelector,
    TaxelFeatureTransformer,
    WindowFeatureTransformer,
)

CLASSIFIERS = ("HM-SVM", "SVC", "LDA", "kNN", "NCM")
"""Classifier names, in report order."""
SVM_C = 16.0
"""Penalty of both SVMs (the vibration study's choice)."""
TOP_K = (3, 7, 14)
"""Numbers of best-ranked features tried (those below the feature count)."""
QUICK_TOP_K = (7,)
QUICK_OTHER_CLASSIFIERS = ("HM-SVM", "LDA")
"""In quick mode every classifier runs on the reference feature set, these two on the others."""


def make_classifier(name: str, n_features: int, random_state: int = 0) -> object:
    """Return an unfitted classifier of :data:`CLASSIFIERS` for ``n_features`` standardised features."""
    from sklearn.discriminant_analysis import LinearDiscriminantAnalysis
    from sklearn.neighbors import KNeighborsClassifier, NearestCentroid

    from ..svm import SVC, HierarchicalSVC

    gamma = 1.0 / n_features
    factories: dict[str, Callable[[], object]] = {
        "HM-SVM": lambda: HierarchicalSVC(C=SVM_C, gamma=gamma, random_state=random_state),
        "SVC": lambda: SVC(C=SVM_C, gamma=gamma, random_state=random_state),
        "LDA": LinearDiscriminantAnalysis,
        "kNN": lambda: KNeighborsClassifier(n_neighbors=3, metric="cityblock", weights="distance"),
        "NCM": NearestCentroid,
    }
    if name not in factories:
        raise ValueError(f"classifier must be one of {CLASSIFIERS}, got {name!r}")
    return factories[name]()


@dataclass(frozen=True)
class FeatureSet:
    """A way from one raw input to features.

    Attributes
    ----------
    name : str
        E.g. ``"fused 12"``, ``"21 features, W = 800"``, ``"top 7 of 21, W = 800"``.
    input : str
        Key of the raw input (:attr:`~.inputs.Samples.key`).
    make : callable
        Returns a fresh (unfitted) ``features`` step.
    n_features : int
        Features the classifier sees.
    select : int or None
        Keep the ``select`` best-ranked features.
    """

    name: str
    input: str
    make: Callable[[], object]
    n_features: int
    select: int | None = None


@dataclass
class Candidate:
    """One candidate model: a classifier on a feature set.

    Attributes
    ----------
    name : str
        ``"<classifier> | <feature set>"``, unique in a study.
    classifier : str
    features : str
    input : str
    estimator : sklearn.pipeline.Pipeline
        Unfitted; steps ``features``, (``select``), ``scale``, ``classifier``.
    """

    name: str
    classifier: str
    features: str
    input: str
    estimator: Pipeline


def build_pipeline(features: FeatureSet, classifier: str, random_state: int = 0) -> Pipeline:
    """Return the unfitted ``Pipeline`` of ``classifier`` on ``features``."""
    steps = [("features", features.make())]
    if features.select is not None:
        steps.append(("select", RankedFeatureSelector(features.select)))
    steps += [
        ("scale", StandardScaler()),
        ("classifier", make_classifier(classifier, features.n_features, random_state)),
    ]
    return Pipeline(steps)


def feature_sets(
    kind: str,
    input_shape: tuple[int, ...],
    *,
    windows: Sequence[int] = (),
    n_features: int | None = None,
    quick: bool = False,
    threshold: float | str = "auto",
    erosion: int | str = "relative",
    contact: str = "raises",
) -> tuple[list[FeatureSet], list[str]]:
    """Return the feature sets for an input kind, the reference one first, and notes on what was left out.

    Parameters
    ----------
    kind : {"vibration", "image", "pressure", "features"}
    input_shape : tuple
        Shape of one sample of the raw input (``(T, 3, H, W)``, ``(T, H, W)`` or ``(F,)``); unused
        for vibration.
    windows : sequence of int
        Vibration: the window sizes to try, the reference one first.
    n_features : int, optional
        Feature file: the number of columns.
    quick : bool
        Fewer best-ranked subsets.
    threshold, erosion, contact
        The image pipeline's constants (see :mod:`.transformers`); ``threshold="auto"`` is decided by
        the caller before (the study's 240/255 or ``"otsu"``); for pressure maps it means ``"display"``.
    """
    top_k = QUICK_TOP_K if quick else TOP_K
    notes: list[str] = []
    sets: list[FeatureSet] = []
    if kind == "vibration":
        if not windows:
            raise ValueError("windows must list at least one window size for vibration data")
        ref = windows[0]
        for w in windows:
            sets.append(FeatureSet(f"21 features, W = {w}", f"windows-{w}", WindowFeatureTransformer, 21))
        for k in top_k:
            sets.append(
                FeatureSet(
                    f"top {k} of 21, W = {ref}", f"windows-{ref}", WindowFeatureTransformer, k, select=k
                )
            )
        sets = [sets[0], *sets[len(windows) :], *sets[1 : len(windows)]]  # reference, its subsets, other W
        return sets, notes
    if kind == "features":
        if n_features is None:
            raise ValueError("n_features is needed for a feature file")
        sets.append(FeatureSet(f"all {n_features} features", "features", FeaturePassthrough, n_features))
        for k in top_k:
            if k < n_features:
                sets.append(
                    FeatureSet(f"top {k} of {n_features}", "features", FeaturePassthrough, k, select=k)
                )
        return sets, notes
    if kind not in ("image", "pressure"):
        raise ValueError(f"kind must be 'vibration', 'image', 'pressure' or 'features', got {kind!r}")
    n_frames, height, width = input_shape[0], input_shape[-2], input_shape[-1]
    if kind == "image":

        def image(fuse: bool) -> Callable[[], object]:
            return lambda: ImageFeatureTransformer(fuse=fuse, threshold=threshold, erosion=erosion)

    else:
        pressure_threshold = "display" if threshold == "auto" else threshold

        def image(fuse: bool) -> Callable[[], object]:
            return lambda: PressureImageFeatures(
                fuse=fuse, threshold=pressure_threshold, erosion=erosion, contact=contact
            )

    key = "frames" if kind == "image" else "pressure"
    sets.append(FeatureSet("fused 12", key, image(True), 12))
    sets.append(FeatureSet(f"per-frame {n_frames * 12}", key, image(False), n_frames * 12))
    taxels = height * width
    if taxels <= MAX_TAXELS and n_frames >= 2:
        sets.append(FeatureSet(f"per-taxel {taxels * 7}", key, TaxelFeatureTransformer, taxels * 7))
    else:
        why = f"{height} x {width} = {taxels} > {MAX_TAXELS}" if taxels > MAX_TAXELS else "a single frame"
        notes.append(f"per-taxel time-series features left out ({why})")
    return sets, notes


def build_candidates(
    sets: Sequence[FeatureSet],
    *,
    quick: bool = False,
    classifiers: Sequence[str] | None = None,
    random_state: int = 0,
) -> list[Candidate]:
    """Return the candidates: every classifier on every feature set (quick: every classifier on the
    first set, :data:`QUICK_OTHER_CLASSIFIERS` on the others), only those in ``classifiers`` if given."""
    if classifiers is not None:
        unknown = sorted(set(classifiers) - set(CLASSIFIERS))
        if unknown or not classifiers:
            raise ValueError(f"classifiers must name some of {CLASSIFIERS}, got {list(classifiers)}")
    out = []
    for i, fs in enumerate(sets):
        names = CLASSIFIERS if (i == 0 or not quick) else QUICK_OTHER_CLASSIFIERS
        for clf in names:
            if classifiers is not None and clf not in classifiers:
                continue
            out.append(
                Candidate(f"{clf} | {fs.name}", clf, fs.name, fs.input, build_pipeline(fs, clf, random_state))
            )
    return out


__all__ = [
    "CLASSIFIERS",
    "TOP_K",
    "Candidate",
    "FeatureSet",
    "build_candidates",
    "build_pipeline",
    "feature_sets",
    "make_classifier",
]
