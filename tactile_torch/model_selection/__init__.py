"""Model selection: every fold, every cross-validation and every tuning of the library, for every study.

Shaped as scikit-learn's ``model_selection``: ``_split`` makes the folds, ``_validation``
cross-validates, ``_search`` tunes (the batched grid search of the SVMs, the studies' protocols);
``_tuning``, ``_models``, ``_tasks`` and ``_sklearn_cv`` are their parts. The public names below are
the package's. It serves the trade-off (:mod:`tactile_torch.tradeoff`), ``train``
(:mod:`tactile_torch.training`), the breaking points (:mod:`tactile_torch.robustness`) and the report's
studies, and it is the one home of fold making:

* **every fold and hold-out** (``_split``): :func:`sample_folds` (explorations
  and feature rows, grouped when every class has two groups), :func:`window_folds` (windows of
  recordings: grouped by session or recording, else time blocks with guard windows), method 1's
  :func:`rotating_splits`, :func:`stratified_folds` and :func:`group_folds` for the studies,
  :func:`time_holdout` (each recording cut in time order); the studies' scikit-learn
  cross-validation on those folds through :func:`fold_predictions` and :func:`fold_scores`;
* **folds that keep groups apart**: :func:`make_folds` (stratified, grouped by recording, session or
  object) and, inside each outer training part, :func:`inner_splits` for tuning;
* **feature caching**: models are ``Pipeline``\\ s whose first step is named ``"features"``; models with
  equal feature steps (class and parameters, :func:`signature`) share them, and a step that needs no fit
  (scikit-learn's ``requires_fit`` tag is False, :func:`needs_fit`: the one protocol) is computed once
  on all samples;
* **nested tuning**: :class:`Tuning` chooses a model's hyper-parameters on inner folds of every outer
  training part (the SVMs through the batched :class:`~tactile_torch.model_selection.SVMGridSearchCV`,
  anything else through scikit-learn's ``GridSearchCV``); its time counts in the fit time;
* **the studies' protocols** (``_search``): method 1's rotating 60/20/20 splits with validation
  (:func:`grid_search_validation`, :func:`run_holdout_protocol`), method 2's stratified grid search
  (:func:`stratified_grid_search`) and feature ranking (:func:`rank_feature_groups`);
* **tasks on any joblib backend**: the (model x fold) tasks run in this process, on joblib's workers
  (``"loky"``, ``"threading"``) or on a Dask cluster (``"dask"``, the optional extra ``dask``)
  through :class:`Backend`; every task derives its seed from the names (:func:`seed_of`), so results
  do not depend on the backend or the number of workers.

:func:`cross_validate` returns per model a :class:`CVResult`: every sample's out-of-fold prediction
with its group and fold, the accuracy per fold, fit time with tuning (and tuning alone), the
parameters chosen per fold, and :meth:`CVResult.final_model` to refit the tuned model on all data.

Examples
--------
>>> import numpy as np
>>> from tactile_torch.model_selection import Tuning, cross_validate, make_folds
>>> from sklearn.discriminant_analysis import LinearDiscriminantAnalysis
>>> from sklearn.neighbors import KNeighborsClassifier
>>> rng = np.random.default_rng(0)
>>> y = np.repeat([0, 1, 2], 20)
>>> X = rng.normal(size=(60, 4)) + 2.0 * np.eye(3, 4)[y]
>>> groups = np.arange(60) // 5                       # 12 recordings of 5 samples
>>> folds = make_folds(y, groups, 4, seed=0)
>>> res = cross_validate(
...     {"LDA": LinearDiscriminantAnalysis(), "kNN": KNeighborsClassifier()}, X, y, folds,
...     groups=groups, tuning={"kNN": Tuning({"n_neighbors": [1, 5, 9]})})
>>> len(res["kNN"].params), sorted(res["kNN"].params[0])
(4, ['n_neighbors'])
>>> bool((res["LDA"].fold >= 0).all())                # every sample tested once
True
"""

from .._exports import lazy_exports

__getattr__, __dir__, __all__ = lazy_exports(
    __name__,
    {
        "_validation": ("CVResult", "cross_validate"),
        "_sklearn_cv": ("fold_predictions", "fold_scores"),
        "_split": (
            "Split",
            "cap_per_class",
            "fold_units",
            "group_folds",
            "group_ids",
            "odd_even_split",
            "rotating_splits",
            "sample_folds",
            "stratified_folds",
            "stratified_splitter",
            "time_holdout",
            "window_folds",
        ),
        "_models": (
            "Folds",
            "Models",
            "inner_splits",
            "last_input",
            "make_folds",
            "needs_fit",
            "seed_of",
            "signature",
            "take",
            "with_params",
        ),
        "_tasks": ("BACKENDS", "Backend", "as_backend", "progress_bar"),
        "_tuning": ("PROTOCOLS", "Tuning", "tune"),
        "_search": (
            "ProtocolResult",
            "SVMGridSearchCV",
            "VIBRATION_STUDY_C",
            "VIBRATION_STUDY_GAMMA",
            "grid_search_validation",
            "parameter_grid",
            "rank_feature_groups",
            "run_holdout_protocol",
            "stratified_grid_search",
            "supports_batched_search",
        ),
    },
)
