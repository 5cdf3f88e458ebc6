"""Colours (matplotlib's names as used by the report, grey levels "0.35",
the default colour cycle C0..C9) and three colour maps (viridis, RdBu_r,
Greys) as key tables, interpolated linearly. The key colours are
matplotlib's (sampled at 17 points), so the pages look as before."""

from __future__ import annotations

import numpy as np

__all__ = ["rgb", "colormap", "CYCLE"]

_TAB = {"tab:blue": "1f77b4", "tab:orange": "ff7f0e", "tab:green": "2ca02c",
        "tab:red": "d62728", "tab:purple": "9467bd", "tab:brown": "8c564b",
        "tab:pink": "e377c2", "tab:gray": "7f7f7f", "tab:grey": "7f7f7f",
        "tab:olive": "bcbd22", "tab:cyan": "17becf"}
CYCLE = list(_TAB.values())[:7] + ["7f7f7f", "bcbd22", "17becf"]
_NAMED = {"black": "000000", "white": "ffffff", "red": "ff0000", "blue": "0000ff",
          "green": "008000", "gray": "808080", "grey": "808080", "orange": "ffa500",
          "k": "000000", "w": "ffffff", "r": "ff0000", "b": "0000ff", "g": "008000"}


def rgb(color) -> tuple:
    """``(r, g, b)`` in 0..1 of a colour name, grey level string, hex
    string, ``Cn`` or a tuple."""
    if isinstance(color, (tuple, list, np.ndarray)):
        return tuple(float(c) for c in color[:3])
    c = str(color)
    if c in _TAB:
        c = _TAB[c]
    elif c in _NAMED:
        c = _NAMED[c]
    elif len(c) == 2 and c[0] == "C" and c[1].isdigit():
        c = CYCLE[int(c[1])]
    else:
        try:
            g = float(c)
            return (g, g, g)
        except ValueError:
            pass
    c = c.lstrip("#")
    if len(c) != 6:
        raise ValueError(f"unknown colour {color!r}")
    return tuple(int(c[i:i + 2], 16) / 255.0 for i in (0, 2, 4))


# 17 keys at 0, 1/16, ..., 1 (matplotlib's colormaps, rounded to 1/255)
_MAPS = {
    "viridis": "440154 48186a 472d7b 424086 3b528b 33638d 2c728e 26828e 21918c 1fa088"
               " 28ae80 3fbc73 5ec962 84d44b addc30 d8e219 fde725",
    "RdBu_r": "053061 175290 2a71b2 3f8ec0 6bacd1 9bc9e0 c2ddec e0ecf3 f7f6f6 fbe5d8"
              " fbccb4 f5aa89 e48066 d05548 ba2832 930e26 67001f",
    "Greys": "ffffff f7f7f7 f0f0f0 e4e4e4 d9d9d9 cbcbcb bdbdbd a9a9a9 959595 848484"
             " 727272 626262 515151 3a3a3a 242424 111111 000000",
}


def colormap(name: str, values, vmin: float, vmax: float) -> np.ndarray:
    """RGB (..., 3) uint8 of ``values`` through the colour map ``name``
    between ``vmin`` and ``vmax`` (clipped)."""
    keys = np.array([[int(h[i:i + 2], 16) for i in (0, 2, 4)] for h in _MAPS[name].split()],
                    float)
    t = (np.asarray(values, float) - vmin) / ((vmax - vmin) or 1.0)
    t = np.clip(np.nan_to_num(t, nan=0.0), 0.0, 1.0) * (len(keys) - 1)
    i = np.minimum(t.astype(int), len(keys) - 2)
    f = (t - i)[..., None]
    return np.round(keys[i] * (1 - f) + keys[i + 1] * f).astype(np.uint8)
