"""A user's 2D pose network given as ``"module:function"`` in the project.

The function is called with one RGB crop (H, W, 3) uint8 and returns the
joints of one person as an array (J, 3) of x, y (pixels of the crop) and
confidence, or None. ``skeleton`` in ``[mocap.source]`` names the joints (a
skeleton of :mod:`photogram.mocap.body.skeleton`). The module is imported from
the project folder (searched first) or ``sys.path``.

Importing a module runs its code, so a project file alone never does it:
the caller must pass ``allow=True``, which the command line does only with
``--allow-plugin`` (docs/mocap.md). Which module is imported, from which
file, is logged as a warning before the import.
"""

from __future__ import annotations

import importlib
import importlib.machinery
import logging
import sys
from pathlib import Path

import numpy as np

from photogram.errors import InputError
from photogram.mocap.body.skeleton import Skeleton
from photogram.mocap.sources.base import ImageDetector

__all__ = ["PluginDetector", "load_function", "ALLOW_OPTION", "refuse_plugin"]

log = logging.getLogger(__name__)

#: the command-line option that allows a project's plugin to be imported
ALLOW_OPTION = "--allow-plugin"


def refuse_plugin(target: str) -> InputError:
    """The error for a plugin network without the opt-in."""
    module_name = str(target).partition(":")[0]
    return InputError(f"network {target!r} of kind \"plugin\" imports and runs the Python "
                      f"module {module_name!r}; photogram runs no code named in a project "
                      f"file without an explicit opt-in",
                      hint=f"if you trust this project and its module, add {ALLOW_OPTION} "
                           f"to the command line")


def load_function(target: str, folder: Path | None = None, *, allow: bool = False):
    """Import ``"module:function"`` (the project folder is searched first).

    Parameters
    ----------
    target : str
        ``"module:function"``.
    folder : Path, optional
        The project folder, searched before ``sys.path``.
    allow : bool
        The user's opt-in (``--allow-plugin``); without it nothing is
        imported.

    Raises
    ------
    InputError
        No opt-in, a malformed target, a module that cannot be imported or
        has no such function.
    """
    module_name, _, attr = str(target).partition(":")
    if not module_name or not attr or not all(
            part.isidentifier() for part in module_name.split(".") + [attr]):
        raise InputError(f"network {target!r} is not of the form \"module:function\"",
                         hint='a module name and a function name, e.g. "mynet:detect"')
    if not allow:
        raise refuse_plugin(target)
    added = False
    if folder is not None and str(folder) not in sys.path:
        sys.path.insert(0, str(folder))
        added = True
    try:
        # where the top-level module is, found without running any of its code
        top = module_name.split(".")[0]
        spec = None if top in sys.modules else importlib.machinery.PathFinder.find_spec(top)
        origin = ("already imported" if top in sys.modules else
                  getattr(spec, "origin", None) or "(not found)")
        log.warning("plugin: importing module %r from %s (network %r, allowed by %s)",
                    module_name, origin, target, ALLOW_OPTION, extra={"immediate": True})
        module = importlib.import_module(module_name)
    except ImportError as exc:
        raise InputError(f"cannot import module {module_name!r} of network {target!r}: {exc}",
                         hint="put the module beside the project file or on PYTHONPATH") \
            from None
    finally:
        if added:
            sys.path.remove(str(folder))
    function = getattr(module, attr, None)
    if not callable(function):
        raise InputError(f"module {module_name!r} has no function {attr!r}")
    return function


class PluginDetector(ImageDetector):
    """Wraps a user function as an :class:`ImageDetector`."""

    def __init__(self, function, skeleton: Skeleton, name: str = "plugin"):
        self.function = function
        self.skeleton = skeleton
        self.name = name

    def __call__(self, image: np.ndarray):
        out = self.function(image)
        if out is None:
            return None
        out = np.asarray(out, dtype=float)
        if out.shape != (self.skeleton.n_joints, 3):
            raise InputError(f"network {self.name} returned an array of shape {out.shape}, "
                             f"expected ({self.skeleton.n_joints}, 3) for skeleton "
                             f"{self.skeleton.name}")
        return out
