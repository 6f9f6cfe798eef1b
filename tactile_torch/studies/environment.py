"""Report section: the machine, the library versions and the data the run used."""

from __future__ import annotations

import os
import platform

from .. import __version__
from ..data import shared_data_dir

TITLE = "Environment and data"


def run(section, ctx) -> None:
    import numpy
    import scipy
    import sklearn
    import torch

    section.table(
        [
            {"item": "tactile-torch", "value": __version__},
            {"item": "python", "value": platform.python_version()},
            {"item": "torch", "value": torch.__version__},
            {
                "item": "numpy / scipy / scikit-learn",
                "value": f"{numpy.__version__} / {scipy.__version__} / {sklearn.__version__}",
            },
            {
                "item": "machine",
                "value": f"{platform.machine()}, {os.cpu_count()} cores, torch threads {torch.get_num_threads()}",
            },
            {"item": "seed", "value": ctx.random_state},
            {
                "item": "mode",
                "value": "quick (--quick)" if ctx.quick else ("full (--full)" if ctx.full else "default"),
            },
        ],
        caption="Software and machine",
    )
    root = shared_data_dir()
    if root is None:
        section.text(
            "The shared real data (`../shared/data`) is absent: only the bundled synthetic data is used."
        )
        return
    rows = [
        {"data set": p.name, "provenance": "yes" if (p / "PROVENANCE.md").exists() else "no"}
        for p in sorted(root.iterdir())
        if p.is_dir()
    ]
    section.table(rows, caption=f"Real data sets found in `{root}`")
