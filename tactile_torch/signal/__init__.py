"""Vibration features of accelerometer windows (method 2: surfaces from vibration), as batched torch ops.

A triaxial recording ``(n, 3)`` is cut into windows ``(B, 3, W)`` by :func:`sliding_windows`;
:func:`window_features` summarises every window by 21 numbers, 7 per axis in axis-major order
(:data:`FEATURE_NAMES`)::

    [x_var, x_skew, x_kurt, x_m5, x_tv, x_cross, x_hf, y_var, ..., z_hf]

:class:`FeatureScaler` scales them to unit standard deviation (the supervised path, an RBF SVM
follows); :class:`ClusteringTransform` is the unsupervised path's transform (``sqrt`` / ``log`` of
the scale features, standardisation, PCA to 3 components; a Pitman-Yor mixture follows). Both are
scikit-learn transformers (fitted on tensors or arrays, ``transform`` returns the kind it was given);
their ``to_module()`` gives the fitted transform as a torch module (:class:`ScaleFeatures`,
:class:`ClusteringProjection`), so that the whole inference path (raw window → features → scaler or
transform) exports to one ONNX graph.

The package's private modules: ``_features`` (windows and their features), ``_transforms`` (the
fitted transforms).

Definitions (every choice a reference could disagree on)
--------------------------------------------------------
For one axis ``a`` of a window, ``a[0], ..., a[W-1]``, ``W >= 2``, with biased central moments
``m_p = mean((a - mean(a))**p)``:

``var``
    ``m_2 * W / (W - 1)``: the unbiased variance (``ddof=1``, ``numpy.var(a, ddof=1)``).
``skew``
    ``m_3 / m_2**1.5``: the biased (population) skewness, ``scipy.stats.skew(a)``.
``kurt``
    ``m_4 / m_2**2``: the biased Pearson kurtosis (3 for a normal),
    ``scipy.stats.kurtosis(a, fisher=False)``.
``m5``
    ``m_5 / m_2**2.5``: the fifth standardised moment with biased central moments,
    ``scipy.stats.moment(a, 5) / numpy.var(a)**2.5``.
``tv``
    ``sum(|a[t+1] - a[t]|)``: the total variation, in the units of ``a``.
``cross``
    The number of crossings of the 20 thresholds ``th_k = min + (k * (max - min)) / 21``,
    ``k = 1, ..., 20``, evenly spaced strictly between the window's minimum and maximum and computed
    in the window's dtype with exactly that order of operations. A sample is *above* a threshold when
    ``a[t] > th_k``; a sample equal to the threshold counts as not above it. A crossing is a change
    of that state between consecutive samples, so a signal that touches a threshold and turns back
    does not cross it, and ``0, th, 1`` crosses it once. The count is summed over the 20 thresholds:
    ``sum_k sum_t [a[t] > th_k] != [a[t+1] > th_k]``. It equals the explicit loop over thresholds
    bit for bit, ties included (tested on quantised signals and on signals lying on the thresholds).
``hf``
    ``sum_k |rfft(a)[k]|`` over the bins whose frequency lies strictly above a quarter of the sample
    rate, ``W // 4 < k <= W // 2`` (``k > W / 4``), with the unnormalised DFT of ``numpy.fft.rfft``.
    The DC bin is never included; the Nyquist bin (even ``W``) is. For ``W = 800`` these are the
    200 bins ``201 .. 400``; for odd ``W = 201``, the 50 bins ``51 .. 100``. ``hf`` grows with ``W``
    (about as ``W**1.5`` for broadband noise).

Degenerate and extreme windows
------------------------------
- A constant window (a stylus at rest) has ``var = tv = cross = hf = 0``, and its standardised
  moments, undefined (``0 / 0``), are **defined as 0** (``skew = kurt = m5 = 0``); scipy returns NaN.
- The moments are computed in float64 from the deviations divided by the window's range, whatever
  the input dtype, and the spectrum from the window minus its first sample: the features are finite
  and accurate for any scale and offset (a 1 g gravity offset costs no float32 accuracy, values of
  1e30 do not overflow ``m_5``), as long as the variance itself fits in the dtype.
- A spike or clipped (saturated) samples need no special case: every feature stays finite.
- NaN or inf samples raise ``ValueError`` (in eager mode; an exported ONNX graph cannot raise, its
  outputs are then non-finite, so check the input before running it).

Examples
--------
>>> import torch
>>> from tactile_torch.signal import sliding_windows, window_features
>>> rec = torch.randn(8000, 3)                  # 10 s of a triaxial recording at 800 Hz
>>> window_features(sliding_windows(rec, 800, 400)).shape
torch.Size([19, 21])
"""

from .._exports import lazy_exports

__getattr__, __dir__, __all__ = lazy_exports(
    __name__,
    {
        "_features": (
            "AXES",
            "AXIS_FEATURES",
            "CLUSTERING_FEATURE_NAMES",
            "FEATURE_NAMES",
            "N_THRESHOLDS",
            "WindowFeatures",
            "sliding_windows",
            "window_features",
        ),
        "_transforms": (
            "ClusteringProjection",
            "ClusteringTransform",
            "FeatureScaler",
            "ScaleFeatures",
            "clustering_features",
            "fit_clustering_transform",
        ),
    },
)
