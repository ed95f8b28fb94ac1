"""Lazy re-exports: a package lists its public names and the module each lives in; nothing is imported until a
name is first used (so `import mjtraj.core.lqr` loads numpy, not MuJoCo, SciPy or Gymnasium)."""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Any


def lazy_exports(namespace: dict[str, Any], exports: dict[str, str]
                 ) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """The module-level `__getattr__` and `__dir__` of a package whose public names are `exports`.

    Args:
      namespace: the package's `globals()`; a name is cached there once imported.
      exports: public name -> the absolute module that defines it.
    """
    package = namespace["__name__"]

    def __getattr__(name: str) -> Any:
        module = exports.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(module), name)
        namespace[name] = value
        return value

    def __dir__() -> list[str]:
        return sorted(set(namespace) | set(exports))

    return __getattr__, __dir__
