"""Every public name's docstring has numpydoc's sections (issue 43, point 6).

Walks the public API as users see it: every name in the ``__all__`` of every public package and the
public methods of its classes written here (theirs and their tactile_torch bases', not those
inherited from scikit-learn or torch; properties and torch's ``extra_repr`` hook aside), and
asks of each numpydoc docstring (class docstring and ``__init__`` docstring together for a class):

- ``Parameters`` when it takes any argument (``self``/``cls`` aside; a dataclass's ``Attributes``
  are its parameters);
- ``Returns`` (or ``Yields``) for a function or method that returns something (no ``-> None``),
  naming the shape of a returned tensor or array (a ``(``) when it is annotated as one;
- ``Raises`` for a public function that takes an argument (validation at the entry names it);
- ``Examples`` for a public function or class (methods are shown in their class's example).

Names written before this rule and not yet complete are :data:`GAPS` (``name: missing sections``); the
list may only shrink: a listed name that becomes complete, or loses one of its gaps, fails the test
until the list says so, and a new name with a gap fails it too.
"""

from __future__ import annotations

import dataclasses
import functools
import importlib
import inspect
import pkgutil
import re
from pathlib import Path

import pytest

import tactile_torch

SECTIONS = ("Parameters", "Returns", "Raises", "Examples")
GAPS_FILE = Path(__file__).with_name("docstring_gaps.txt")


def _public_packages() -> list[str]:
    names = [tactile_torch.__name__]
    for info in pkgutil.walk_packages(tactile_torch.__path__, prefix="tactile_torch."):
        if info.ispkg and not any(part.startswith("_") for part in info.name.split(".")[1:]):
            names.append(info.name)
    return names


def _sections(doc: str | None) -> set[str]:
    """The numpydoc section titles of ``doc`` (a title underlined by dashes)."""
    text = inspect.cleandoc(doc or "")
    return set(re.findall(r"^(\w+)\n-{3,}$", text, re.M))


def _takes_arguments(function) -> bool:
    try:
        parameters = list(inspect.signature(function).parameters)
    except (TypeError, ValueError):
        return False
    return bool([p for p in parameters if p not in ("self", "cls")])


def _returns_nothing(function) -> bool:
    annotation = inspect.signature(function).return_annotation
    return annotation in (None, "None")


def _returns_array(function) -> bool:
    annotation = str(inspect.signature(function).return_annotation)
    return annotation != str(inspect.Signature.empty) and bool(re.search(r"Tensor|ndarray", annotation))


def _returns_section(doc: str | None) -> str:
    text = inspect.cleandoc(doc or "")
    match = re.search(r"^(?:Returns|Yields)\n-{3,}\n(.*?)(?=^\w+\n-{3,}$|\Z)", text, re.M | re.S)
    return match.group(1) if match else ""


def _function_gaps(function, *, public: bool) -> list[str]:
    doc = function.__doc__
    have = _sections(doc)
    if "Yields" in have:
        have.add("Returns")
    wanted = []
    if _takes_arguments(function):
        wanted.append("Parameters")
    if not _returns_nothing(function) and function.__name__ != "__init__":
        wanted.append("Returns")
    if public and _takes_arguments(function):
        wanted.append("Raises")
    if public:
        wanted.append("Examples")
    missing = [s for s in wanted if s not in have]
    if "Returns" in wanted and "Returns" in have and _returns_array(function):
        if "(" not in _returns_section(doc):
            missing.append("Returns shape")
    return missing


def _own_methods(cls) -> dict[str, object]:
    """Public methods written in tactile_torch: the class's and its (private) tactile_torch bases'."""
    methods = {}
    for owner in cls.__mro__:
        if not owner.__module__.startswith("tactile_torch"):
            continue
        for name, value in vars(owner).items():
            # properties read as attributes (documented by their one line); extra_repr is torch's hook
            if name in methods or name.startswith("_") or isinstance(value, property) or name == "extra_repr":
                continue
            function = getattr(value, "__func__", value)  # classmethod / staticmethod
            if inspect.isfunction(function) and function.__module__.startswith("tactile_torch"):
                methods[name] = function
    return methods


def _class_gaps(cls) -> list[str]:
    have = _sections(cls.__doc__) | _sections(vars(cls).get("__init__", object).__doc__)
    if dataclasses.is_dataclass(cls) and "Attributes" in have:
        have.add("Parameters")  # a dataclass's fields are its parameters
    wanted = ["Examples"]
    # the constructor users call: the first __init__ up the MRO, if one of ours (nn.Module's
    # *args/**kwargs are no settings)
    owner = next((c for c in cls.__mro__ if "__init__" in vars(c)), object)
    init = vars(owner)["__init__"]
    if owner.__module__.startswith("tactile_torch") and _takes_arguments(init):
        wanted.insert(0, "Parameters")
    return [s for s in wanted if s not in have]


@functools.cache
def docstring_gaps() -> dict[str, list[str]]:
    """``qualified name`` -> the sections its docstring lacks, for every public name with a gap."""
    gaps: dict[str, list[str]] = {}
    seen: set[int] = set()
    for package_name in _public_packages():
        package = importlib.import_module(package_name)
        for name in package.__all__:
            obj = getattr(package, name)
            if id(obj) in seen or inspect.ismodule(obj):
                continue
            seen.add(id(obj))
            qualified = f"{package_name}.{name}"
            if inspect.isclass(obj):
                if not obj.__module__.startswith("tactile_torch"):
                    continue
                found = {qualified: _class_gaps(obj)}
                for method_name, method in _own_methods(obj).items():
                    found[f"{qualified}.{method_name}"] = _function_gaps(method, public=False)
            elif inspect.isfunction(obj):
                found = {qualified: _function_gaps(obj, public=True)}
            else:
                continue  # constants: documented where they are defined
            gaps.update({k: v for k, v in found.items() if v})
    return gaps


def _listed() -> dict[str, list[str]]:
    listed = {}
    for line in GAPS_FILE.read_text(encoding="utf-8").splitlines():
        if line.strip() and not line.startswith("#"):
            name, _, missing = line.partition(":")
            listed[name.strip()] = [s.strip() for s in missing.split(",")]
    return listed


def test_every_public_name_has_its_docstring_sections():
    found = docstring_gaps()
    listed = _listed()
    new = {k: v for k, v in found.items() if k not in listed or not set(v) <= set(listed[k])}
    assert not new, f"docstring sections missing (numpydoc; see this module's docstring): {new}"
    closed = {k: v for k, v in listed.items() if set(found.get(k, [])) != set(v)}
    assert not closed, (
        f"gaps closed: update {GAPS_FILE.name} (the list may only shrink): "
        f"{ {k: found.get(k, []) for k in closed} }"
    )


def test_the_walk_finds_the_public_api_and_a_missing_section():
    found_names = set()
    for package_name in _public_packages():
        found_names.update(f"{package_name}.{n}" for n in importlib.import_module(package_name).__all__)
    assert {"tactile_torch.image.exploration_features", "tactile_torch.export.export_onnx"} <= found_names

    def undocumented(x: int) -> int:
        """Return x."""
        return x

    assert _function_gaps(undocumented, public=True) == ["Parameters", "Returns", "Raises", "Examples"]
    assert _function_gaps(tactile_torch.image.erode, public=True) == []


@pytest.mark.parametrize(
    "name", ["tactile_torch.image.exploration_features", "tactile_torch.image.ExplorationFeatures"]
)
def test_the_names_issue_43_found_incomplete_are_complete(name):
    assert name not in docstring_gaps()
