"""Fuzzing with a corpus of malformed inputs (tests/fuzz/corpus.py): every
table and TOML key of the example projects and every importer's input,
truncated, with wrong types, NaN/inf, huge values, duplicate ids, unknown
references, bytes that are not UTF-8, BOM, CRLF, tabs; run through
`photogram check`, the mocap reading stage, `photogram import` and (a
representative subset) calibrate, orient, intersect, montecarlo and mocap.

Each case must end with exit code 0 or 2, on 2 with exactly one line on
stderr naming the file (and the mutated line where the input is
line-based), and never with a traceback. benchmarks/fuzz.py runs the same
cases and prints the figures (all of them; the test suite runs every third
case unless PHOTOGRAM_FUZZ_FULL=1)."""

from __future__ import annotations

import os

import pytest

from fuzz.corpus import build_cases, run_case, staged_base

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow

# the example projects, copied once per session (the cases are built from them
# at collection; tests/test_fuzz_hypothesis.py uses the same copy)
BASE = staged_base()
# `make test` runs every third case (all files and mutation kinds still appear;
# about 25 s); PHOTOGRAM_FUZZ_FULL=1 or benchmarks/fuzz.py runs all of them
CASES = build_cases(BASE)[::1 if os.environ.get("PHOTOGRAM_FUZZ_FULL") else 3]


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_malformed_input_is_one_line_and_exit_2(case):
    res, bad = run_case(case, BASE)           # its own empty output folder
    assert not bad, f"{case.id}: {bad}\nstdout: {res.out[-2000:]}\nstderr: {res.err[-3000:]}"
