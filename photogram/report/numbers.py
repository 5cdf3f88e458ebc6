"""Number formatting of the report's tables (plain text, no locale)."""

from __future__ import annotations

import math

__all__ = ["num", "fixed", "sig", "decimals_for", "pair", "pct", "finite"]


def finite(x) -> bool:
    try:
        return x is not None and math.isfinite(float(x))
    except (TypeError, ValueError):
        return False


def num(x, digits: int = 4) -> str:
    """``digits`` significant digits, scientific notation only when needed;
    '-' for missing values."""
    if not finite(x):
        return "-"
    x = float(x)
    if x == 0:
        return "0"
    e = math.floor(math.log10(abs(x)))
    if -4 <= e < digits + 2:
        d = max(0, digits - 1 - e)
        return f"{x:.{d}f}"
    return f"{x:.{digits - 1}e}"


def fixed(x, d: int) -> str:
    return f"{float(x):.{d}f}" if finite(x) else "-"


def decimals_for(sigma, digits: int = 2, most: int = 10) -> int:
    """Decimals that show ``digits`` significant digits of ``sigma``."""
    if not finite(sigma) or float(sigma) <= 0:
        return 4
    return int(min(most, max(0, digits - 1 - math.floor(math.log10(float(sigma))))))


def sig(x, digits: int = 2) -> str:
    """A sigma: ``digits`` significant digits."""
    return num(x, digits)


def pair(value, sigma) -> tuple[str, str]:
    """Value and sigma with as many decimals as the sigma's 2 significant
    digits need (scientific notation for very small or large numbers)."""
    if not finite(value):
        return "-", sig(sigma)
    if not finite(sigma) or float(sigma) <= 0:
        return f"{float(value):.8g}", ("fixed" if finite(sigma) else "-")
    v, s = float(value), float(sigma)
    if abs(s) < 1e-4 or max(abs(v), s) >= 1e7:
        e = math.floor(math.log10(max(abs(v), s)))
        d = max(1, e - math.floor(math.log10(s)) + 1)
        return f"{v:.{d}e}", f"{s:.1e}"
    d = decimals_for(s)
    return f"{v:.{d}f}", f"{s:.{d}f}"


def pct(x, d: int = 1) -> str:
    return f"{100 * float(x):.{d}f} %" if finite(x) else "-"
