"""Public names of a package, imported from their modules only when first used.

A package's ``__init__`` names what other packages use (``from labrig.rig import
build_rig``) without importing it: importing a package then costs nothing (the command
line starts before numba, h5py or OpenCV is needed) and cannot close an import cycle
through a package's ``__init__`` (the rig's assembly needs the runner, whose interlocks
need the rig's device contracts).
"""

from __future__ import annotations

import importlib
from collections.abc import Callable


def lazy_exports(
    package: str, owners: dict[str, list[str]]
) -> tuple[Callable[[str], object], Callable[[], list[str]]]:
    """The ``__getattr__`` and ``__dir__`` of ``package``: ``owners`` maps each module of
    the package (relative name) to the public names it defines."""
    module_of = {name: module for module, names in owners.items() for name in names}

    def __getattr__(name: str) -> object:
        module = module_of.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        return getattr(importlib.import_module(f"{package}.{module}"), name)

    def __dir__() -> list[str]:
        return sorted(module_of)

    return __getattr__, __dir__
