"""The one ``__init__`` style of tactile-torch's packages: a declared public API, imported on first use.

Every package's ``__init__.py`` holds its docstring, one mapping ``{submodule: (public names it
defines, ...)}`` and one call::

    from .._exports import lazy_exports

    __getattr__, __dir__, __all__ = lazy_exports(
        __name__,
        {"estimators": ("SVC", "HierarchicalSVC"), "inference": ("SVMInference",)},
    )

``from tactile_torch.svm import SVC`` then imports ``tactile_torch.svm.estimators`` when ``SVC`` is
first asked for (PEP 562 module ``__getattr__``), and no other submodule: a path that needs one part of
a package does not pay for the others (numba kernels loaded from their cache, scikit-learn, torch for
the torch-free packages). ``__all__`` is exactly the mapping's names plus the ``defined`` names
(light, dependency-free ones written in the ``__init__`` itself, such as ``__version__``), so the
public API of a package is one list, read in one place. A name that is not in the mapping is not
public: import it from its submodule.

A name that moves to another module is simply moved (nothing has been released): its callers are
updated and ``CHANGELOG.md`` lists the move. The lookup of a lazy export is not an import of the
module's code: a package's ``__init__`` does not import its submodules
(``tests/project/test_imports.py`` counts import statements only).

This module imports nothing but the standard library (the torch-free robot package uses it too).
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Iterable, Mapping


def lazy_exports(
    package: str,
    exports: Mapping[str, Iterable[str]],
    *,
    defined: Iterable[str] = (),
) -> tuple[Callable[[str], object], Callable[[], list[str]], list[str]]:
    """Return a package's ``__getattr__``, ``__dir__`` and ``__all__`` for the public names it declares.

    Parameters
    ----------
    package : str
        The package's ``__name__``.
    exports : mapping of str to iterable of str
        Submodule of the package (relative, e.g. ``"estimators"`` or ``"_features"``) -> the public
        names it defines.
    defined : iterable of str
        Public names defined in the ``__init__`` itself (listed in ``__all__``, never imported).

    Returns
    -------
    getattr : callable
        ``getattr(name)`` imports ``name``'s submodule and returns the attribute; it stores it in the
        package's namespace, so that later lookups are plain attribute reads (the same object: the
        result of a lookup never depends on what ran before). Other names raise ``AttributeError``.
    dir : callable
        The package's namespace and its public names, sorted.
    all : list of str
        The public names, sorted.

    Raises
    ------
    ValueError
        If a name is declared twice (in two submodules, or in a submodule and ``defined``).

    Examples
    --------
    >>> getattr_, dir_, all_ = lazy_exports("json", {"decoder": ("JSONDecodeError",)}, defined=("dumps",))
    >>> all_, getattr_("JSONDecodeError").__name__
    (['JSONDecodeError', 'dumps'], 'JSONDecodeError')
    """
    homes: dict[str, str] = {}
    for name in defined:
        homes[name] = ""
    for module, names in exports.items():
        for name in names:
            if name in homes:
                where = homes[name] or "the __init__"
                raise ValueError(f"{package}: public name {name!r} declared twice ({where} and {module})")
            homes[name] = module
    public = sorted(homes)

    def __getattr__(name: str) -> object:
        home = homes.get(name)
        if not home:  # unknown, or a `defined` name that the __init__ failed to define
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(f"{package}.{home}"), name)
        setattr(sys.modules[package], name, value)
        return value

    def __dir__() -> list[str]:
        return sorted({*vars(sys.modules[package]), *public})

    return __getattr__, __dir__, public
