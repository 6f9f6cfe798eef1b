"""The classifier catalogue: one entry per classifier, one lower-case key used everywhere.

``tactile-torch train --method``, ``tactile-torch tradeoff --classifiers``, the trade-off candidates and the
studies all read this table, so a classifier has one name, one set of default settings and one tuning grid.

======  ========  ============================================================================  ==========
key     name      estimator (defaults)                                                          tuned over
======  ========  ============================================================================  ==========
hmsvm   HM-SVM    :class:`tactile_torch.svm.HierarchicalSVC`, RBF, ``C = 16``, ``gamma="scale"``  C x gamma
svc     SVC       :class:`tactile_torch.svm.SVC` (one-vs-one), same kernel and defaults          C x gamma
lda     LDA       scikit-learn ``LinearDiscriminantAnalysis`` (SVD solver)                       shrinkage
knn     kNN       ``StableKNeighborsClassifier(3, metric="cityblock", weights="distance")``     k
ncm     NCM       nearest class mean, scikit-learn ``NearestCentroid`` (Euclidean)               shrinkage
======  ========  ============================================================================  ==========

Learned models (family ``"neural"``, and ``"learned front end"``) take a raw input instead of
features (:attr:`ClassifierEntry.raw_input`); :data:`CLASSIFIERS` lists the classical keys (what
``train --method`` accepts), :data:`LEARNED` the others (``tradeoff --classifiers`` accepts both):

==================  ========================  =====================================================  ===========
key                 name                      estimator (:mod:`tactile_torch.neural`)                raw input
==================  ========================  =====================================================  ===========
cnn-small           1-D CNN small             ``WindowCNNClassifier("small")`` (about 4 k parameters)   windows
cnn-large           1-D CNN large             ``WindowCNNClassifier("large")`` (about 90 k)             windows
taxel-cnn           temporal CNN              ``TaxelCNNClassifier()``                                  pressure
image-cnn           exploration CNN           ``ExplorationCNNClassifier()``                            frames
learned-front-end   learned front end         ``LearnedFrontEndClassifier()`` (method 1, hinge head)    frames
learned-cutoff      learned cut-off           ``LearnedCutoffClassifier()`` (method 2, hinge head)      windows
==================  ========================  =====================================================  ===========

They are not tuned over a grid: the networks stop early on an inner validation split of each training
fold instead.

``svm`` is an alias of ``svc`` (what ``tactile-torch train --method svm`` always meant), and the display
names (``"HM-SVM"``, ``"kNN"`` ...) resolve to their keys in any case (:func:`resolve`), so old spellings
keep working.

Tuning grids (:func:`param_grid`) are in the classifier's own parameter names, for features standardised
to unit variance (every catalogue classifier is fitted behind a ``StandardScaler``): the RBF ``gamma`` is
given relative to ``1 / n_features`` (scikit-learn's ``"scale"`` on standardised features). The quick grid
is a subset that still tunes every parameter the full grid tunes.

Examples
--------
>>> make_classifier("knn")
StableKNeighborsClassifier(algorithm='brute', metric='cityblock', n_neighbors=3,
                           weights='distance')
>>> resolve("HM-SVM"), resolve("svm"), display_name("ncm")
('hmsvm', 'svc', 'NCM')
>>> sorted(param_grid("svc", 4, quick=True))
['C', 'gamma']
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

SVM_C = 16.0
"""Default penalty of both SVMs (the vibration study's choice)."""
SVM_C_GRID = (1.0, 4.0, 16.0, 64.0, 256.0, 1024.0)
SVM_QUICK_C_GRID = (1.0, 16.0, 256.0)
SVM_GAMMA_GRID = (0.25, 1.0, 4.0)
"""RBF ``gamma`` values of the SVM grid, as multiples of ``1 / n_features``."""
SVM_QUICK_GAMMA_GRID = (0.25, 1.0)
KNN_K = 3
"""The study's number of neighbours (city-block distance, inverse-distance weights)."""
KNN_K_GRID = (1, 3, 5, 7, 11, 15)
KNN_QUICK_K_GRID = (1, 3, 7)
LDA_SHRINKAGE_GRID = ("auto", 0.1, 0.3, 0.6, 0.9)
LDA_QUICK_SHRINKAGE_GRID = ("auto",)
NCM_SHRINK_GRID = (None, 0.1, 0.3, 1.0)
NCM_QUICK_SHRINK_GRID = (None, 0.3)
KERNEL_CLASSIFIERS = ("hmsvm", "svc")
"""The SVMs: the keys that take ``C``, ``gamma`` and ``kernel``."""
SCALINGS = ("standard", "unit", "unit-population", None)
"""The feature scalings of :func:`classifier_pipeline`."""


@dataclass(frozen=True)
class ClassifierEntry:
    """One classifier of the catalogue.

    Attributes
    ----------
    key : str
        Lower-case key (CLI choices, ``train --method``, ``tradeoff --classifiers``).
    name : str
        Display name in tables and charts (``"HM-SVM"``).
    family : str
        ``"classical"`` (``"neural"`` for learned feature models).
    description : str
        One line: the estimator and its default settings.
    build : callable
        ``build(random_state, **params)`` returns the unfitted estimator.
    grid : callable
        ``grid(n_features, quick)`` returns the tuning grid (a dict, or a list of dicts as
        ``GridSearchCV`` takes) in the estimator's own parameter names; ``{}`` when nothing is tuned.
    needs_scaling : bool
        Whether it expects standardised features (a ``StandardScaler`` before it).
    exportable : bool
        Whether a fitted one has an ONNX inference path (:func:`tactile_torch.export.classifier_inference.inference_module`
        or the SVMs' ``to_module``).
    aliases : tuple of str
        Other lower-case spellings that resolve to ``key``.
    raw_input : tuple of str
        Learned models: the raw inputs they take (``"windows"``, ``"pressure"``, ``"frames"``); empty
        for the classical ones, which take features.
    """

    key: str
    name: str
    family: str
    description: str
    build: Callable[..., Any]
    grid: Callable[[int, bool], Any]
    needs_scaling: bool = True
    exportable: bool = True
    aliases: tuple[str, ...] = ()
    raw_input: tuple[str, ...] = ()


def _hmsvm(random_state=None, **params):
    from .svm import HierarchicalSVC

    return HierarchicalSVC(**{"C": SVM_C, "gamma": "scale", "random_state": random_state, **params})


def _svc(random_state=None, **params):
    from .svm import SVC

    return SVC(**{"C": SVM_C, "gamma": "scale", "random_state": random_state, **params})


def _lda(random_state=None, **params):
    from sklearn.discriminant_analysis import LinearDiscriminantAnalysis

    return LinearDiscriminantAnalysis(**params)


def _knn(random_state=None, **params):
    from .neighbors import StableKNeighborsClassifier

    # Ties in training order, as the exported graph resolves them (tactile_torch.neighbors): its
    # neighbours are found by brute force, so no search tree is built at fit.
    settings = {"n_neighbors": KNN_K, "metric": "cityblock", "weights": "distance", "algorithm": "brute"}
    return StableKNeighborsClassifier(**{**settings, **params})


def _ncm(random_state=None, **params):
    from sklearn.neighbors import NearestCentroid

    return NearestCentroid(**params)


def _neural(name: str, *args: Any):
    def build(random_state=None, **params):
        from . import neural

        return getattr(neural, name)(*args, **{"random_state": random_state, **params})

    return build


def _no_grid(n_features: int, quick: bool) -> dict:
    return {}


def _svm_grid(n_features: int, quick: bool) -> dict:
    cs = SVM_QUICK_C_GRID if quick else SVM_C_GRID
    rel = SVM_QUICK_GAMMA_GRID if quick else SVM_GAMMA_GRID
    return {"C": list(cs), "gamma": [r / n_features for r in rel]}


def _lda_grid(n_features: int, quick: bool) -> list:
    shrinkage = LDA_QUICK_SHRINKAGE_GRID if quick else LDA_SHRINKAGE_GRID
    return [{"solver": ["svd"]}, {"solver": ["lsqr"], "shrinkage": list(shrinkage)}]


def _knn_grid(n_features: int, quick: bool) -> dict:
    return {"n_neighbors": list(KNN_QUICK_K_GRID if quick else KNN_K_GRID)}


def _ncm_grid(n_features: int, quick: bool) -> dict:
    return {"shrink_threshold": list(NCM_QUICK_SHRINK_GRID if quick else NCM_SHRINK_GRID)}


ENTRIES: dict[str, ClassifierEntry] = {
    e.key: e
    for e in (
        ClassifierEntry(
            "hmsvm",
            "HM-SVM",
            "classical",
            "tactile_torch.svm.HierarchicalSVC, RBF, C = 16, gamma = 'scale' (method 1's classifier)",
            _hmsvm,
            _svm_grid,
        ),
        ClassifierEntry(
            "svc",
            "SVC",
            "classical",
            "tactile_torch.svm.SVC, one-vs-one RBF SVM (as scikit-learn's), C = 16, gamma = 'scale'",
            _svc,
            _svm_grid,
            aliases=("svm",),
        ),
        ClassifierEntry(
            "lda",
            "LDA",
            "classical",
            "scikit-learn LinearDiscriminantAnalysis (SVD solver; tuned: lsqr with shrinkage)",
            _lda,
            _lda_grid,
        ),
        ClassifierEntry(
            "knn",
            "kNN",
            "classical",
            "k nearest neighbours (scikit-learn's, ties in training order: tactile_torch.neighbors), k = 3, "
            "city-block distance, inverse-distance weights (the study's)",
            _knn,
            _knn_grid,
        ),
        ClassifierEntry(
            "ncm",
            "NCM",
            "classical",
            "nearest class mean, scikit-learn NearestCentroid (Euclidean)",
            _ncm,
            _ncm_grid,
        ),
        *(
            ClassifierEntry(
                key,
                name,
                family,
                description,
                _neural(cls, *args),
                _no_grid,
                needs_scaling=False,
                raw_input=raw,
            )
            for key, name, family, description, cls, args, raw in (
                (
                    "cnn-small",
                    "1-D CNN small",
                    "neural",
                    "1-D CNN on the raw window, about 4 k parameters",
                    "WindowCNNClassifier",
                    ("small",),
                    ("windows",),
                ),
                (
                    "cnn-large",
                    "1-D CNN large",
                    "neural",
                    "1-D CNN on the raw window, about 90 k parameters",
                    "WindowCNNClassifier",
                    ("large",),
                    ("windows",),
                ),
                (
                    "taxel-cnn",
                    "temporal CNN",
                    "neural",
                    "temporal CNN over every taxel of raw pressure maps",
                    "TaxelCNNClassifier",
                    (),
                    ("pressure",),
                ),
                (
                    "image-cnn",
                    "exploration CNN",
                    "neural",
                    "small CNN on an exploration's mean and max darkness",
                    "ExplorationCNNClassifier",
                    (),
                    ("frames",),
                ),
                (
                    "learned-front-end",
                    "learned front end",
                    "learned front end",
                    "method 1 with threshold and edge threshold learned through the soft ops, hinge head",
                    "LearnedFrontEndClassifier",
                    (),
                    ("frames",),
                ),
                (
                    "learned-cutoff",
                    "learned cut-off",
                    "learned front end",
                    "method 2 with the spectral cut-off learned through a soft mask, hinge head",
                    "LearnedCutoffClassifier",
                    (),
                    ("windows",),
                ),
            )
        ),
    )
}
"""The catalogue, in report order: the classical classifiers, then the learned models."""

CLASSIFIERS: tuple[str, ...] = tuple(k for k, e in ENTRIES.items() if e.family == "classical")
"""Keys of the classical classifiers (they take features), in report order."""
LEARNED: tuple[str, ...] = tuple(k for k, e in ENTRIES.items() if e.family != "classical")
"""Keys of the learned models (they take a raw input: :attr:`ClassifierEntry.raw_input`)."""


def resolve(name: str) -> str:
    """Return the catalogue key of a key, an alias or a display name (any case).

    Raises
    ------
    ValueError
        For a name the catalogue does not know, listing the keys.
    """
    if isinstance(name, str):
        text = name.strip().lower()
        for e in ENTRIES.values():
            if text == e.key or text == e.name.lower() or text in e.aliases:
                return e.key
    raise ValueError(
        f"classifier must be one of {list(CLASSIFIERS)} (or svm for svc) or a learned model of "
        f"{list(LEARNED)}, got {name!r}"
    )


def entry(name: str) -> ClassifierEntry:
    """Return the :class:`ClassifierEntry` of a key, alias or display name (see :func:`resolve`)."""
    return ENTRIES[resolve(name)]


def display_name(name: str) -> str:
    """Return the display name (``"HM-SVM"``) of a key, alias or display name."""
    return entry(name).name


def choices() -> list[str]:
    """Return the classical keys and aliases a command line accepts for ``--method``."""
    return [*CLASSIFIERS, *(a for e in ENTRIES.values() for a in e.aliases)]


def make_classifier(
    key: str, *, random_state: int | None = None, n_features: int | None = None, **params: Any
) -> Any:
    """Return an unfitted classifier of the catalogue with its default settings, overridden by ``params``.

    Parameters
    ----------
    key : str
        A key, alias or display name (:func:`resolve`).
    random_state : int or None
        For the estimators that draw random numbers (the SVMs); ignored by the others.
    n_features : int, optional
        For the SVMs (:data:`KERNEL_CLASSIFIERS`): ``gamma = 1 / n_features`` (scikit-learn's
        ``"scale"`` on standardised features), unless ``params`` set ``gamma``; ignored by the others.
    **params
        Estimator parameters (``C=4.0``, ``n_neighbors=5`` ...).
    """
    key = resolve(key)
    if n_features is not None and key in KERNEL_CLASSIFIERS:
        params = {"gamma": 1.0 / n_features, **params}
    return entry(key).build(random_state, **params)


def classifier_pipeline(
    classifier: str | Any,
    features: Any = None,
    *,
    select: int | None = None,
    scaling: str | None = "standard",
    random_state: int | None = None,
    n_features: int | None = None,
    **params: Any,
) -> Any:
    """Return the unfitted ``Pipeline`` ``features -> [select] -> scale -> classifier``: the one recipe.

    Steps, by name: ``features`` (when given: a transformer from raw input to features),
    ``select`` (when ``select`` is set: the ``select`` best-ranked features,
    :class:`~tactile_torch.features.transformers.RankedFeatureSelector`), ``scale`` (unless
    ``scaling`` is ``None``) and ``classifier`` (tuning grids address it as ``classifier__<name>``).

    Parameters
    ----------
    classifier : str or estimator
        A catalogue key, alias or display name (made by :func:`make_classifier` with ``random_state``,
        ``n_features`` and ``params``), or an unfitted estimator used as it is.
    features : transformer, optional
    select : int, optional
    scaling : {"standard", "unit", "unit-population"} or None, default "standard"
        ``"standard"``: centred, unit variance (scikit-learn's ``StandardScaler``; the trade-off's
        candidates and method 1's studies). ``"unit"``: unit standard deviation (``ddof=1``), not
        centred (:class:`~tactile_torch.signal.FeatureScaler`; method 2's study, and the scale ``train``
        keeps in a model file). ``"unit-population"``: the same with the population standard deviation
        (``StandardScaler(with_mean=False)``; the breaking-point and claims sections' method-2 models).

    Examples
    --------
    >>> classifier_pipeline("knn", select=7, scaling="unit").named_steps.keys()
    dict_keys(['select', 'scale', 'classifier'])
    """
    if scaling not in SCALINGS:
        raise ValueError(f"scaling must be one of {list(SCALINGS)}, got {scaling!r}")
    from sklearn.pipeline import Pipeline

    if isinstance(classifier, str):
        classifier = make_classifier(classifier, random_state=random_state, n_features=n_features, **params)
    steps = [] if features is None else [("features", features)]
    if select is not None:
        from .features.transformers import RankedFeatureSelector

        steps.append(("select", RankedFeatureSelector(select)))
    if scaling == "unit":
        from .signal import FeatureScaler

        steps.append(("scale", FeatureScaler()))
    elif scaling is not None:
        from sklearn.preprocessing import StandardScaler

        steps.append(("scale", StandardScaler(with_mean=scaling == "standard")))
    return Pipeline([*steps, ("classifier", classifier)])


def param_grid(key: str, n_features: int, *, quick: bool = False) -> dict | list:
    """Return the tuning grid of a classifier for ``n_features`` standardised features.

    A dict (or a list of dicts, as ``GridSearchCV`` takes) of the estimator's own parameter names;
    ``gamma`` values are absolute (the relative grid times ``1 / n_features``).
    """
    if isinstance(n_features, bool) or not isinstance(n_features, int) or n_features < 1:
        raise ValueError(f"n_features must be an integer >= 1, got {n_features!r}")
    return entry(key).grid(n_features, quick)


def prefixed(grid: dict | list, prefix: str) -> dict | list:
    """Return ``grid`` with every parameter name prefixed (``"classifier__"`` for a pipeline's step)."""
    if isinstance(grid, Mapping):
        return {f"{prefix}{k}": list(v) for k, v in grid.items()}
    return [prefixed(g, prefix) for g in grid]


__all__ = [
    "CLASSIFIERS",
    "ENTRIES",
    "KERNEL_CLASSIFIERS",
    "LEARNED",
    "SCALINGS",
    "ClassifierEntry",
    "choices",
    "classifier_pipeline",
    "display_name",
    "entry",
    "make_classifier",
    "param_grid",
    "prefixed",
    "resolve",
]
