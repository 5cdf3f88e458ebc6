"""Fuzzing helpers: the malformed-input corpus (:mod:`fuzz.corpus`), shared by
tests/test_fuzz_corpus.py, tests/test_fuzz_hypothesis.py and benchmarks/fuzz.py."""
