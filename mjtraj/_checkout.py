"""Importing mjtraj from a source checkout, where envs/ and assets/ sit beside mjtraj/ instead of inside it.

Installation maps them into the package (pyproject.toml's package-dir). A checkout on sys.path (`python -m pytest`
or `python -m mjtraj` from its root, a Ray worker started there) finds them through this finder, the same
mapping setuptools' editable installs use. An installed mjtraj never installs it.
"""

from __future__ import annotations

import importlib.abc
import importlib.machinery
import importlib.util
import sys
from pathlib import Path

MAPPED = ("envs", "assets")
"""Subpackages of mjtraj that live at the top of the repository."""


class CheckoutFinder(importlib.abc.MetaPathFinder):
    """Finds mjtraj.envs and mjtraj.assets in the checkout's envs/ and assets/."""

    def __init__(self, root: Path) -> None:
        self.folders = {f"mjtraj.{name}": root / name for name in MAPPED}

    def find_spec(self, fullname: str, path: object = None,
                  target: object = None) -> importlib.machinery.ModuleSpec | None:
        folder = self.folders.get(fullname)
        if folder is None:
            return None
        return importlib.util.spec_from_file_location(fullname, folder / "__init__.py",
                                                      submodule_search_locations=[str(folder)])


def checkout_root(package_dir: Path) -> Path | None:
    """The repository `package_dir` (mjtraj/) belongs to if it is a checkout's (no envs/ inside it, the repository's
    envs/ and mjtraj's pyproject.toml beside it); None for an installed mjtraj."""
    root = package_dir.parent
    if (package_dir / "envs").exists() or not (root / "envs" / "__init__.py").is_file():
        return None
    if not (root / "pyproject.toml").is_file() or 'name = "mjtraj"' not in (root / "pyproject.toml").read_text():
        return None
    return root


def install(package_dir: Path) -> None:
    """Install the finder if `package_dir` (mjtraj/) is a checkout's (`checkout_root`)."""
    root = checkout_root(package_dir)
    if root is not None and not any(isinstance(finder, CheckoutFinder) for finder in sys.meta_path):
        sys.meta_path.append(CheckoutFinder(root))
