"""The real BAL problems of ../shared/data/bal (read-only), read and
solved with the default settings once per test session for the tests that
need them (tests/test_bal.py, tests/test_adjust_rcs_sparse.py): reading
the bz2 text and the dense solve cost seconds each."""

from __future__ import annotations

import functools
from pathlib import Path
from types import SimpleNamespace

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "bal"


@functools.lru_cache(maxsize=None)
def read(name: str):
    """``read_bal`` of ``DATA/<name>.txt.bz2`` (shared: do not change it)."""
    from photogram.io.bal import read_bal
    return read_bal(DATA / f"{name}.txt.bz2")


@functools.lru_cache(maxsize=None)
def solved(name: str) -> SimpleNamespace:
    """:func:`read`'s problem built (``build_bal_problem``, behind-camera
    observations dropped) and solved by ``solve_bal`` with its default
    options: ``built`` (after the solve), ``dropped`` (count),
    ``cost_before`` (the engine's cost at the start), ``summary``."""
    from photogram.bundle.bal import build_bal_problem, solve_bal
    built = build_bal_problem(read(name))
    p = built.problem
    cost_before = p.cost(p.state)
    summary = solve_bal(built)
    return SimpleNamespace(built=built, dropped=len(built.dropped), cost_before=cost_before,
                           summary=summary)
