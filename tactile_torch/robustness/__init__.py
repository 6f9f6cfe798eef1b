"""Breaking points: how far each degradation can go before a model's accuracy falls halfway to chance.

A :class:`~.degradations.Degradation` is a small declarative record: what it degrades (``kinds`` of raw input), where
it acts (``stage``), the levels to sweep from mildest to harshest, and a pure function that applies one
level. :func:`~.sweeps.sweep` evaluates clone-able scikit-learn estimators on their raw input (frames
``(N, T, 3, H, W)`` or pressure maps ``(N, T, H, W)``, signal windows ``(N, 3, W)``, or features
``(N, F)``) under every level, by grouped cross-validation, and returns one :class:`Curve` per factor
and model with its :class:`~.results.BreakingPoint`. :func:`~.sweeps.breaking_points` is the same for one
estimator.

Modules: :mod:`.degradations` (the :class:`~.degradations.Degradation` record and the default factors,
:data:`~.degradations.FACTORS`), :mod:`.sweeps` (:func:`~.sweeps.sweep`, :func:`~.sweeps.breaking_points`,
:func:`~.sweeps.recording_blocks`), :mod:`.results` (the curves and breaking points they return),
:mod:`.charts` (figures of the curves) and :mod:`.output` (the table, and the files a sweep writes).

Where a degradation acts (``stage``):

==============  ========================================================================================
``"features"``  the classifier's input, at test time: the output of every step before the last one of
                a :class:`~sklearn.pipeline.Pipeline` (features, standardised when a scaler precedes
                the classifier), or the raw input of a bare classifier. The study's Table 3.
``"test"``      the raw test input only; the model was trained on clean data (a disturbance met at
                run time: noise on the images or the signals).
``"retrain"``   the raw training and test input alike, the model retrained at each level (a sensor or
                protocol setting: fewer frames, coarser sensels, shorter windows, lower rate, coarser
                quantisation, smaller range).
``"train"``     the training split only (fewer training samples per class: the learning curve).
``"parameter"`` a parameter of the model's ``features`` step (the erosion element), retrained.
``"time"``      the split: train on the first part of every recording, test on later parts (drift).
==============  ========================================================================================

The breaking point of a curve is the first level at which accuracy is at or below
``chance + (clean - chance) / 2``, ``chance = 1 / n_classes``, interpolated linearly between the
last level above and the first at or below (in the level's value, or between the two levels' names
when the levels are not numbers). Its 95 % interval comes from a cluster bootstrap over the groups
(resampling whole recordings, objects or sessions with their pooled test predictions; the model is
not refitted): 2.5th and 97.5th percentiles of the replicates' breaking points, a replicate that
never falls counting as beyond the harshest level.

Examples
--------
>>> import numpy as np
>>> from sklearn.discriminant_analysis import LinearDiscriminantAnalysis
>>> from tactile_torch.robustness.sweeps import breaking_points
>>> rng = np.random.default_rng(0)
>>> X = rng.normal(size=(60, 4)) + np.repeat(np.eye(3, 4) * 3, 20, axis=0)
>>> y = np.repeat(np.arange(3), 20)
>>> curves = breaking_points(LinearDiscriminantAnalysis(), X, y, factors=["feature SNR"], random_state=0)
>>> curves[0].breaking.status
'reached'
"""

from .._exports import lazy_exports

__getattr__, __dir__, __all__ = lazy_exports(
    __name__,
    {
        "degradations": ("FACTORS", "INPUT_KINDS", "STAGES", "Degradation", "factor", "factors_for"),
        "results": ("BreakingPoint", "Curve", "SweepResult"),
        "sweeps": ("breaking_points", "infer_kind", "recording_blocks", "sweep"),
        "charts": ("plot_factor", "plot_factors", "plot_grid"),
        "output": ("breaking_summary", "breaking_table", "write_breaking_points"),
    },
)
