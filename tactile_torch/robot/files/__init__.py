"""Data and model files on the robot side (NumPy only): every format read and written in one place.

Submodules: ``formats`` (the data formats: ``.npz`` explorations, recordings and features; their
readers and writers), ``csv_logs`` (CSV logs with declared columns, units and time unit),
``data_sources`` (what a ``--data`` argument names: files, folders, bags, with their options),
``frame_recordings`` and ``labelled`` (frame recordings, labelled data), ``npz`` (bounded ``.npz``
reads), ``model_file`` (the one writer and reader of model files: plain arrays and a JSON header, no
pickle), ``naming`` (classes and sessions from file names), ``safe_write`` (atomic writes that never
overwrite an input or a device), ``sample_times`` (rates and gaps from time stamps).
"""

from ..._exports import lazy_exports

__getattr__, __dir__, __all__ = lazy_exports(
    __name__,
    {
        "model_file": ("ModelFile", "load_model_file", "save_model_file"),
        "formats": ("read_data", "read_explorations", "read_features", "read_recordings"),
        "data_sources": ("DataOptions", "read_source"),
    },
)
