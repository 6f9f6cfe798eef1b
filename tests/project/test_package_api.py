"""Every package's ``__init__`` declares its public API one way (tactile_torch._exports.lazy_exports)."""

import importlib
import pkgutil
import subprocess
import sys

import pytest

import tactile_torch
from tactile_torch._exports import lazy_exports


def _packages() -> list[str]:
    names = [tactile_torch.__name__]
    for info in pkgutil.walk_packages(tactile_torch.__path__, prefix="tactile_torch."):
        if info.ispkg and not info.name.rsplit(".", 1)[-1].startswith("_"):
            names.append(info.name)
    return names


PACKAGES = _packages()


def test_the_packages_are_found():
    assert {
        "tactile_torch.svm",
        "tactile_torch.mixture",
        "tactile_torch.data",
        "tactile_torch.studies",
    } <= set(PACKAGES)


@pytest.mark.parametrize("name", PACKAGES)
def test_every_package_declares_its_api_through_lazy_exports(name):
    package = importlib.import_module(name)
    source = package.__spec__.loader.get_source(name)
    assert "lazy_exports(" in source, f"{name}/__init__.py does not use tactile_torch._exports.lazy_exports"
    assert package.__all__ == sorted(set(package.__all__)), f"{name}.__all__ is not sorted and unique"
    for public in package.__all__:
        assert getattr(package, public) is not None
        assert public in dir(package)
    with pytest.raises(AttributeError, match=f"module '{name}' has no attribute 'not_a_public_name'"):
        package.not_a_public_name  # noqa: B018


def test_solver_internals_are_not_public():
    svm = importlib.import_module("tactile_torch.svm")
    for internal in ("solve_dual", "DualSolution", "KernelData"):
        assert internal not in svm.__all__
    assert {"SVC", "HierarchicalSVC", "SVMInference"} <= set(svm.__all__)


@pytest.mark.parametrize(
    ("statement", "absent"),
    [
        ("import tactile_torch", ("torch", "numpy", "sklearn", "numba")),
        ("import tactile_torch._exports", ("torch", "numpy", "sklearn", "numba")),
        ("import tactile_torch.data", ("torch", "sklearn", "numba")),
        # floor 0: the exceptions and the torch-free checks serve the robot side
        ("import tactile_torch.exceptions", ("torch", "numpy", "sklearn", "numba")),
        ("from tactile_torch.validation import check_count, numpy_rng", ("torch", "sklearn", "numba")),
        (
            "import tactile_torch.robot.files, tactile_torch.robot.stream, tactile_torch.robot.ros2",
            ("torch", "sklearn", "numba"),
        ),
        (
            "import tactile_torch.features, tactile_torch.ood, tactile_torch.export, tactile_torch.model_selection",
            ("torch", "sklearn", "numba"),
        ),
        ("import tactile_torch.mixture", ("torch", "sklearn", "numba")),
        ("from tactile_torch.mixture import GaussianMixtureClassifier", ("sklearn", "numba")),
        ("import tactile_torch.svm, tactile_torch.image, tactile_torch.signal", ("torch",)),
        # the SVMs' inference graph (export, predict) needs torch only, not the compiled solver
        ("from tactile_torch.svm import SVMInference", ("numba", "sklearn")),
        ("from tactile_torch.svm.inference import svm_margins", ("numba", "sklearn")),
    ],
)
def test_importing_a_package_loads_only_what_the_asked_names_need(statement, absent):
    code = f"import sys; {statement}; print(' '.join(m for m in {absent!r} if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == [], f"{statement!r} imported {out.stdout.split()}"


def test_a_name_declared_twice_is_an_error():
    with pytest.raises(ValueError, match=r"pkg: public name 'f' declared twice \(a and b\)"):
        lazy_exports("pkg", {"a": ("f",), "b": ("f",)})
    with pytest.raises(ValueError, match=r"declared twice \(the __init__ and a\)"):
        lazy_exports("pkg", {"a": ("f",)}, defined=("f",))
