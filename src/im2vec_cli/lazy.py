"""Packages whose names load on first use (PEP 562), so that importing one part of a package does
not import what its other parts need: ``trace`` reaches ``raster.curves`` without torch."""

from __future__ import annotations

from collections.abc import Callable
from importlib import import_module


def lazy_names(package: str, where: dict[str, str]) -> tuple[Callable[[str], object], Callable[[], list[str]]]:
    """``__getattr__`` and ``__dir__`` for ``package`` whose public names live in the submodules
    ``where`` gives (name -> submodule); each is imported at its first use and kept."""
    namespace = import_module(package).__dict__

    def getattr_(name: str):
        if name not in where:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(import_module(f"{package}.{where[name]}"), name)
        namespace[name] = value
        return value

    def dir_() -> list[str]:
        return sorted(set(namespace) | set(where))

    return getattr_, dir_
