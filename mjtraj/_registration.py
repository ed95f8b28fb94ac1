"""`gym.make("UR5Track-v0")` after `import mjtraj`, in either import order, without importing Gymnasium.

If Gymnasium is already imported, `register` imports `mjtraj.envs` (which registers the envs) at once. Otherwise
it leaves a finder that, when Gymnasium is first imported, lets it load as usual and then registers the envs.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import importlib.util
import sys
from types import ModuleType


class RegisterAfterGymnasium(importlib.abc.MetaPathFinder):
    """Registers mjtraj's envs right after Gymnasium's first import (and then leaves sys.meta_path)."""

    def find_spec(self, fullname: str, path: object = None,
                  target: object = None) -> importlib.machinery.ModuleSpec | None:
        if fullname != "gymnasium":
            return None
        sys.meta_path.remove(self)
        spec = importlib.util.find_spec(fullname)
        if spec is None or spec.loader is None:
            return spec
        load = spec.loader.exec_module

        def exec_and_register(module: ModuleType) -> None:
            load(module)
            importlib.import_module("mjtraj.envs")

        spec.loader.exec_module = exec_and_register  # type: ignore[method-assign]
        return spec


def register() -> None:
    """Register the envs now if Gymnasium is imported, else as soon as it is."""
    if "gymnasium" in sys.modules:
        importlib.import_module("mjtraj.envs")
    elif not any(isinstance(finder, RegisterAfterGymnasium) for finder in sys.meta_path):
        sys.meta_path.insert(0, RegisterAfterGymnasium())
