"""Speed against accuracy: evaluate candidate models on a data file and recommend the simplest adequate one.

What ``tactile-torch tradeoff`` runs (docs/tradeoff.md). For a data file of the formats in docs/formats.md (image
explorations, raw pressure maps from a small taxel array, vibration recordings or CSV logs, or a
feature matrix), :func:`run_tradeoff` builds candidate models (:mod:`.candidates`: HM-SVM, SVC, LDA,
kNN and nearest class mean on every feature set), cross-validates them with folds that keep related
samples apart (:mod:`.inputs`), exports each to one ONNX file and times it under onnxruntime
(:mod:`.evaluation`, :mod:`tactile_torch.export.parts`), finds the Pareto front of accuracy against time to a decision
and applies the one-standard-error rule (:mod:`.selection`); :func:`write_outputs` writes
``tradeoff.json``, ``tradeoff.md`` and the charts (:mod:`.output`).

Every candidate is a scikit-learn ``Pipeline`` that takes the raw input, with a ``features`` step
(:mod:`tactile_torch.features`) and a ``classifier`` step; ``sklearn.base.clone`` gives an unfitted copy.

Examples
--------
>>> from tactile_torch.tradeoff import run_tradeoff, write_outputs                  # doctest: +SKIP
>>> result = run_tradeoff("recordings.npz", quick=True, out_dir="runs/tradeoff")  # doctest: +SKIP
>>> write_outputs(result, "runs/tradeoff")                                       # doctest: +SKIP
>>> result.recommended                                                           # doctest: +SKIP
'LDA | 21 features, W = 800'
"""

from .._exports import lazy_exports

__getattr__, __dir__, __all__ = lazy_exports(
    __name__,
    {
        "candidates": (
            "CLASSIFIERS",
            "Candidate",
            "CandidateResult",
            "FeatureRecipe",
            "build_candidates",
            "feature_sets",
        ),
        "inputs": ("Samples", "TradeoffData", "load_tradeoff_data"),
        "output": ("summary_lines", "write_outputs"),
        "runner": ("run_tradeoff",),
        "selection": ("fold_interval", "one_standard_error_choice", "pareto_front"),
        "summary": ("TradeoffResult",),
    },
)
