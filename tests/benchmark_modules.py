"""The benchmark scripts of benchmarks/ loaded as modules, for the tests of
their pure helpers (summaries, fits, tables; never timings)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"


def load_benchmark(name: str):
    """``benchmarks/NAME.py`` as a module (named ``NAME_bench``; not
    imported into sys.modules, its ``__main__`` block not run)."""
    spec = importlib.util.spec_from_file_location(f"{name}_bench", BENCHMARKS / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod
