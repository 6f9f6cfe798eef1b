"""Benchmarks of tactile-torch against the SciPy/NumPy/scikit-learn references (``make bench``)."""
