"""``python -m tactile_torch.warmup`` (run by ``make install``): it must reach every compiled kernel.

A kernel module the warm-up does not import, or a kernel compiled without ``cache=True``, would make a
user's first fit in every new process wait for the compiler; both are checked here in a fresh
interpreter (another test may already have imported the kernels into this one).
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

LIBRARY = Path(__file__).resolve().parents[1] / "tactile_torch"

_PROBE = """
import json, sys
from numba.core.registry import CPUDispatcher
from tactile_torch.warmup import warm_up
seconds = warm_up()
modules = json.loads(sys.argv[1])
kernels = {}
for name in modules:
    module = sys.modules.get(name)
    kernels[name] = None if module is None else {
        attr: type(obj._cache).__name__
        for attr, obj in vars(module).items()
        if isinstance(obj, CPUDispatcher) and obj.__module__ == name
    }
print(json.dumps({"seconds": seconds, "kernels": kernels}))
"""


def kernel_modules(library: Path = LIBRARY) -> list[str]:
    """Dotted names of the library's modules that define numba kernels (an ``@njit`` decorator)."""
    return [
        ".".join(path.relative_to(library.parent).with_suffix("").parts)
        for path in sorted(library.rglob("*.py"))
        if re.search(r"^@njit\b", path.read_text(), re.MULTILINE)
    ]


def test_warm_up_loads_every_kernel_module_and_every_kernel_is_cached_on_disk():
    from tactile_torch.warmup import COMPILED_MODULES

    modules = kernel_modules()
    assert "tactile_torch.mixture._gibbs.chain" in modules and "tactile_torch.svm._smo" in modules
    out = subprocess.run(
        [sys.executable, "-c", _PROBE, json.dumps(modules)], capture_output=True, text=True, check=True
    ).stdout
    report = json.loads(out)
    assert set(report["seconds"]) == set(COMPILED_MODULES)
    assert all(s >= 0 for s in report["seconds"].values())
    not_loaded = [name for name, kernels in report["kernels"].items() if kernels is None]
    assert not_loaded == [], "add them (or a module importing them) to warmup.COMPILED_MODULES"
    uncached = [f"{m}.{k}" for m, ks in report["kernels"].items() for k, c in ks.items() if c == "NullCache"]
    assert uncached == [], "compile them with cache=True"
    assert all(report["kernels"].values())  # each module's kernels were found


def test_kernel_modules_finds_a_decorated_function(tmp_path):
    package = tmp_path / "tactile_torch"
    (package / "sub").mkdir(parents=True)
    (package / "plain.py").write_text("def f():\n    return 1  # @njit in a comment is no kernel\n")
    (package / "sub" / "kernels.py").write_text(
        "from numba import njit\n\n\n@njit(cache=True)\ndef f():\n    return 1\n"
    )
    assert kernel_modules(package) == ["tactile_torch.sub.kernels"]


def test_main_prints_one_line_per_module(capsys, monkeypatch):
    from tactile_torch import warmup

    # the imports themselves are the probe's (above); here what main says of them
    monkeypatch.setattr(
        warmup, "warm_up", lambda: {m: 0.25 * i for i, m in enumerate(warmup.COMPILED_MODULES)}
    )
    assert warmup.main() == 0
    lines = capsys.readouterr().err.splitlines()
    assert lines == [f"compiled {m} in {0.25 * i:.1f} s" for i, m in enumerate(warmup.COMPILED_MODULES)]
