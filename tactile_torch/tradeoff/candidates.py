"""The candidate models of a trade-off study: classifiers x feature sets, each a scikit-learn ``Pipeline``.

Every candidate is ``Pipeline([("features", <raw input → features>), ("select", <k best>)?,
("scale", StandardScaler()), ("classifier", <classifier>)])``: it takes the data file's raw input,
so it can be cross-validated, exported whole and swept over input degradations (``sklearn.base.clone``
gives an unfitted copy).

Classifiers come from the catalogue (:mod:`tactile_torch.catalogue`: HM-SVM, SVC, LDA, kNN, NCM, one
set of names and settings for the whole package). :data:`CLASSIFIERS` holds their display names, which
candidate names and tables use; ``classifiers=`` takes keys (``"hmsvm"``) or display names.

Tuning (nested, :class:`tactile_torch.model_selection.Tuning`): every candidate with hyper-parameters is tuned
inside each outer training fold over the catalogue's grid (``quick``: the smaller grid) on 3 inner
folds, grouped where the data's groups allow: the SVMs over C x gamma (the batched
:class:`~tactile_torch.model_selection.SVMGridSearchCV`), kNN over k, LDA over shrinkage, NCM over its
shrink threshold. The study's own model (the HM-SVM on the reference feature set) is tuned as the study
tuned it: on vibration windows by stratified 10-fold grid search (3 folds with ``quick``), method 2's
protocol; on explorations by one validation part of the training folds (60 % train, 20 % validation of
the whole), method 1's protocol. ``tune=False`` runs every candidate at the catalogue's defaults
(``C = 16``, ``gamma = 1 / n_features``, k = 3, plain LDA and NCM), for comparison.

Feature sets by input kind (:func:`feature_sets`): vibration: the 21 features at every allowed window
size and the ``k`` best-ranked of the 21 at the reference window; RGB explorations: fused 12,
per-frame ``T x 12`` and, for frames of at most :data:`~tactile_torch.features.transformers.MAX_TAXELS` pixels, per-taxel
time series; raw pressure maps: the same three through :class:`~tactile_torch.features.transformers.PressureImageFeatures`;
a feature file: all columns and the ``k`` best-ranked.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from sklearn.pipeline import Pipeline

from .. import catalogue
from ..features.transformers import (
    MAX_TAXELS,
    FeaturePassthrough,
    ImageFeatureTransformer,
    PressureImageFeatures,
    RawInput,
    TaxelFeatureTransformer,
    WindowFeatureTransformer,
)
from ..model_selection import CVResult, Tuning

CLASSIFIERS = tuple(catalogue.display_name(key) for key in catalogue.CLASSIFIERS)
"""Classifier display names, in report order (the catalogue's; its keys work too)."""
SVM_C = catalogue.SVM_C
"""Default penalty of both SVMs (the vibration study's choice; tuned unless ``tune=False``)."""
TOP_K = (3, 7, 14)
"""Numbers of best-ranked features tried (those below the feature count)."""
QUICK_TOP_K = (7,)
QUICK_OTHER_CLASSIFIERS = ("HM-SVM", "LDA")
"""In quick mode every classifier runs on the reference feature set, these two on the others."""
INNER_FOLDS = 3
"""Inner folds of every candidate's tuning."""
STUDY_INNER_FOLDS = {"quick": 3, "full": 10}
"""Inner folds of the study's own model on vibration windows (method 2: stratified 10-fold)."""
STUDY_VALIDATION_FOLDS = 4
"""Explorations: the study's model is tuned on one of 4 inner folds of an 80 % training part (20 % of
the whole) after training on the other three (60 %): method 1's 60/20/20 protocol."""


def candidate_tuning(
    name: str, n_features: int, *, quick: bool = False, study: str | None = None
) -> Tuning | None:
    """Return how a candidate's classifier is tuned (see the module notes), ``None`` without a grid.

    ``study`` is ``"vibration"`` or ``"exploration"`` for the study's own model (tuned by its protocol).
    """
    grid = catalogue.param_grid(name, n_features, quick=quick)
    if not grid:
        return None
    grid = catalogue.prefixed(grid, "classifier__")
    if study == "vibration":
        return Tuning(grid, STUDY_INNER_FOLDS["quick" if quick else "full"], "kfold")
    if study == "exploration":
        return Tuning(grid, STUDY_VALIDATION_FOLDS, "validation")
    return Tuning(grid, INNER_FOLDS, "kfold")


@dataclass(frozen=True)
class FeatureRecipe:
    """How one feature set of the study is made: the raw input it reads and the ``features`` step.

    (Not the features themselves: those of a data file are a :class:`tactile_torch.features.files.FeatureSet`.)

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
        The classifier's display name (``"HM-SVM"``).
    features : str
    input : str
    estimator : sklearn.pipeline.Pipeline
        Unfitted, at the catalogue's defaults; steps ``features``, (``select``), ``scale``, ``classifier``.
    key : str
        The classifier's catalogue key (``"hmsvm"``).
    tuning : Tuning or None
        How ``classifier__*`` parameters are chosen inside each training fold; ``None``: not tuned.
    """

    name: str
    classifier: str
    features: str
    input: str
    estimator: Pipeline
    key: str = ""
    tuning: Tuning | None = None


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
) -> tuple[list[FeatureRecipe], list[str]]:
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
        The image pipeline's constants (see :mod:`~tactile_torch.features.transformers`); ``threshold="auto"`` is decided by
        the caller before (the study's 240/255 or ``"otsu"``); for pressure maps it means ``"display"``.
    """
    top_k = QUICK_TOP_K if quick else TOP_K
    notes: list[str] = []
    sets: list[FeatureRecipe] = []
    if kind == "vibration":
        if not windows:
            raise ValueError("windows must list at least one window size for vibration data")
        ref = windows[0]
        for w in windows:
            sets.append(FeatureRecipe(f"21 features, W = {w}", f"windows-{w}", WindowFeatureTransformer, 21))
        for k in top_k:
            sets.append(
                FeatureRecipe(
                    f"top {k} of 21, W = {ref}", f"windows-{ref}", WindowFeatureTransformer, k, select=k
                )
            )
        sets = [sets[0], *sets[len(windows) :], *sets[1 : len(windows)]]  # reference, its subsets, other W
        return sets, notes
    if kind == "features":
        if n_features is None:
            raise ValueError("n_features is needed for a feature file")
        sets.append(FeatureRecipe(f"all {n_features} features", "features", FeaturePassthrough, n_features))
        for k in top_k:
            if k < n_features:
                sets.append(
                    FeatureRecipe(f"top {k} of {n_features}", "features", FeaturePassthrough, k, select=k)
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
    sets.append(FeatureRecipe("fused 12", key, image(True), 12))
    sets.append(FeatureRecipe(f"per-frame {n_frames * 12}", key, image(False), n_frames * 12))
    taxels = height * width
    if taxels <= MAX_TAXELS and n_frames >= 2:
        sets.append(FeatureRecipe(f"per-taxel {taxels * 7}", key, TaxelFeatureTransformer, taxels * 7))
    else:
        why = f"{height} x {width} = {taxels} > {MAX_TAXELS}" if taxels > MAX_TAXELS else "a single frame"
        notes.append(f"per-taxel time-series features left out ({why})")
    return sets, notes


def build_candidates(
    sets: Sequence[FeatureRecipe],
    *,
    quick: bool = False,
    classifiers: Sequence[str] | None = None,
    random_state: int = 0,
    tune: bool = True,
) -> list[Candidate]:
    """Return the candidates: every classifier on every feature set (quick: every classifier on the
    first set, :data:`QUICK_OTHER_CLASSIFIERS` on the others), only those in ``classifiers`` (catalogue
    keys or display names) if given; each with its :func:`candidate_tuning` unless ``tune=False``."""
    wanted = None
    if classifiers is not None:
        try:
            wanted = {catalogue.resolve(c) for c in classifiers}
        except ValueError:
            wanted = set()
        if not wanted or not classifiers:
            raise ValueError(
                f"classifiers must name some of {list(catalogue.CLASSIFIERS)} (or {list(CLASSIFIERS)}), "
                f"got {list(classifiers)}"
            )
    out = []
    for i, fs in enumerate(sets):
        names = CLASSIFIERS if (i == 0 or not quick) else QUICK_OTHER_CLASSIFIERS
        for clf in names:
            key = catalogue.resolve(clf)
            if wanted is not None and key not in wanted:
                continue
            tuning = None
            if tune:
                study = None
                if i == 0 and key == "hmsvm":
                    study = "vibration" if fs.input.startswith("windows") else "exploration"
                    study = None if fs.input == "features" else study
                tuning = candidate_tuning(key, fs.n_features, quick=quick, study=study)
            pipe = catalogue.classifier_pipeline(
                clf, fs.make(), select=fs.select, random_state=random_state, n_features=fs.n_features
            )
            out.append(Candidate(f"{clf} | {fs.name}", clf, fs.name, fs.input, pipe, key, tuning))
    return out


@dataclass
class CandidateResult:
    """What was measured for one candidate (see :mod:`.evaluation`'s notes for the definitions).

    Attributes
    ----------
    candidate : Candidate
    fold_accuracy : list of float
        Empty when fitting failed (see ``notes``).
    fit_s : float
        Mean seconds of one fold's fit, tuning included.
    model : Pipeline or None
        Fitted on the first training fold (the exported one); ``None`` when fitting failed.
    latency_ms, size_bytes, decision_s, onnx_agreement : float or None
        ``None`` when the export failed (see ``notes``).
    onnx_file : str or None
    notes : list of str
        Warnings raised while fitting, export errors.
    parity_predictions : ndarray or None
        The first fold's predictions of its test samples (what the
        exported file must reproduce).
    predictions : ndarray of shape (N,) or None
        Out-of-fold prediction of every sample of the candidate's raw input (``-1`` if never tested),
        for the per-unit accuracies of :mod:`.selection`.
    tune_s : float
        Mean seconds of one fold's tuning (0 when not tuned).
    params : list of dict
        The parameters tuning chose in each fold (``{}`` per fold when not tuned).
    cv : CVResult or None
        The engine's result: every sample's out-of-fold prediction with its group and fold
        (``cv.predictions``, ``cv.groups``, ``cv.fold``) and ``cv.final_model`` to refit the tuned
        candidate on all data.
    n_parameters, memory_mib, family
        The learned numbers, the onnxruntime session's peak memory, ``"classical"``, ``"neural"`` or
        ``"learned front end"``.
    quantisation : {"static", "dynamic"} or None
        An int8 variant's quantisation (:mod:`.learned`); ``None`` for a float candidate.
    variant_of : str or None
        An int8 variant: the name of its float candidate.
    stopped : str or None
        Why the study stopped it early, before its last fold (:mod:`.stopping`); ``None`` when it ran
        every fold. A stopped candidate's accuracy is over the units it was tested on, and it is not
        chosen.
    bare_file : Path or None
        Its first-fold file without the "unknown" rule (what an int8 variant quantises, :mod:`.bundle`).
    train_features : ndarray or None
        The first fold's training features while its timing file is written (its "unknown" rule), then
        ``None``.
    distance : tuple or None
        Its timing file's "unknown" rule: ``(rule, distance part, inputs)`` (:func:`~.bundle.finish_bundle`).
    """

    candidate: Candidate
    fold_accuracy: list[float]
    fit_s: float
    model: Pipeline | None
    latency_ms: float | None = None
    size_bytes: int | None = None
    decision_s: float | None = None
    onnx_agreement: float | None = None
    onnx_file: str | None = None
    notes: list[str] = field(default_factory=list)
    parity_predictions: np.ndarray | None = field(default=None, repr=False)
    predictions: np.ndarray | None = field(default=None, repr=False)
    tune_s: float = 0.0
    params: list[dict] = field(default_factory=list)
    cv: CVResult | None = field(default=None, repr=False)
    n_parameters: int | None = None
    memory_mib: float | None = None
    quantisation: str | None = None
    family: str = "classical"
    variant_of: str | None = None
    stopped: str | None = None
    bare_file: object = field(default=None, repr=False)
    train_features: object = field(default=None, repr=False)
    distance: tuple | None = field(default=None, repr=False)


def features_key(candidate: Candidate) -> tuple:
    """What the candidate's features depend on: its raw input and its ``features`` step (type, parameters)."""
    step = candidate.estimator.named_steps["features"]
    return candidate.input, type(step).__name__, repr(sorted(step.get_params().items()))


def is_learned(model: object) -> bool:
    """Return whether a candidate's (fitted or not) pipeline is a learned model on the raw input."""
    steps = getattr(model, "steps", None)
    return bool(steps) and isinstance(steps[0][1], RawInput)


__all__ = [
    "CLASSIFIERS",
    "TOP_K",
    "Candidate",
    "CandidateResult",
    "FeatureRecipe",
    "build_candidates",
    "candidate_tuning",
    "feature_sets",
    "features_key",
    "is_learned",
]
