"""A user's 2D pose network given as ``"module:function"`` in the project.

The function is called with one RGB crop (H, W, 3) uint8 and returns the
joints of one person as an array (J, 3) of x, y (pixels of the crop) and
confidence, or None. ``skeleton`` in ``[mocap.source]`` names the joints (a
skeleton of :mod:`photogram.mocap.skeleton`). The module is imported from
``sys.path`` plus the project folder.
"""

from __future__ import annotations

import importlib
import sys
from pathlib import Path

import numpy as np

from photogram.errors import InputError
from photogram.mocap.skeleton import Skeleton
from photogram.mocap.sources.base import ImageDetector

__all__ = ["PluginDetector", "load_function"]


def load_function(target: str, folder: Path | None = None):
    """Import ``"module:function"`` (the project folder is searched first)."""
    module_name, _, attr = str(target).partition(":")
    if not module_name or not attr:
        raise InputError(f"network {target!r} is not of the form \"module:function\"")
    added = False
    if folder is not None and str(folder) not in sys.path:
        sys.path.insert(0, str(folder))
        added = True
    try:
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
