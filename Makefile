# Two commands on a fresh machine: `make demo` and `make test`.
# Each creates or updates the local virtual environment .venv by itself.
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: venv test test-fast test-numba demo clean montecarlo bench

# Some machines set PYTHONDONTWRITEBYTECODE=1; then every run recompiles
# photogram and pytest rewrites the asserts of all 250 test modules again
# (about 15 s CPU of collecting, and again in every child process). The
# caches (__pycache__/, ignored by git) are written inside the clone.
unexport PYTHONDONTWRITEBYTECODE

venv: $(STAMP)

# --no-compile: pip would byte-compile every module of every installed
# package (about 22 s CPU for scipy, pandas, matplotlib, dask, ...); without
# it Python compiles, once, only the modules that are imported (about 8-12 s
# CPU in the first `make test`), and caches them as usual.
$(STAMP): setup.cfg pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet --no-compile -e '.[test]'
	touch $(STAMP)

# The layers contract (setup.cfg [importlinter], docs/index.md; a second),
# then the suite: either failing fails the target. pytest exits 5 when it
# collected no tests: that is a failure of the suite.
test: $(STAMP)
	@$(VENV)/bin/lint-imports; lint=$$?; \
	$(PY) -m pytest -q; rc=$$?; \
	if [ $$rc -eq 5 ]; then echo "make test: pytest collected no tests"; exit 1; fi; \
	if [ $$lint -ne 0 ]; then echo "make test: the layers contract is broken (lint-imports)"; exit 1; fi; \
	exit $$rc

# For development: the layers contract, then the suite without the tests
# marked `slow` (pytest -m "not slow"; the marker is registered in setup.cfg
# [tool:pytest], the slow files and tests are listed in docs/benchmarks.md).
# `make test` still runs everything.
test-fast: $(STAMP)
	@$(VENV)/bin/lint-imports; lint=$$?; \
	$(PY) -m pytest -q -m "not slow"; rc=$$?; \
	if [ $$rc -eq 5 ]; then echo "make test-fast: pytest collected no tests"; exit 1; fi; \
	if [ $$lint -ne 0 ]; then echo "make test-fast: the layers contract is broken (lint-imports)"; exit 1; fi; \
	exit $$rc

# The compiled kernels (numba, the optional extra [fast]) in an environment
# of their own, .venv-numba, so that .venv keeps the pure-numpy path that
# `make test` tests: the test files that compare the two paths or test the
# kernels, which skip where numba is missing. .ci/run runs it after `make test`.
NUMBA_VENV := .venv-numba
NUMBA_TESTS := tests/test_adjust_kernels.py tests/test_adjust_rcs_sparse.py tests/test_bal.py tests/test_rcs_coarse.py \
	tests/test_bal_point_rows.py tests/test_bal_point_rows_numpy.py tests/test_rcs_cg_criterion.py tests/test_stats_blockwise.py
$(NUMBA_VENV)/.installed: setup.cfg pyproject.toml
	$(PYTHON) -m venv $(NUMBA_VENV)
	$(NUMBA_VENV)/bin/python -m pip install --quiet --upgrade pip
	$(NUMBA_VENV)/bin/python -m pip install --quiet --no-compile -e '.[test,fast]'
	touch $@

test-numba: $(NUMBA_VENV)/.installed
	$(NUMBA_VENV)/bin/python -c "import numba; print('make test-numba: numba', numba.__version__)"
	$(NUMBA_VENV)/bin/python -m pytest -q -rs $(NUMBA_TESTS)

demo: $(STAMP)
	$(VENV)/bin/photogram demo

clean:
	rm -rf $(VENV) $(NUMBA_VENV) build *.egg-info

# Accuracy by simulation on the demo's results (run `make demo` first).
montecarlo: $(STAMP)
	$(VENV)/bin/photogram montecarlo projects/jumps/montecarlo.prj

# Benchmarks print their figures and end with a RESULT line (docs/benchmarks.md).
bench: $(STAMP)
	$(PY) benchmarks/camcal.py
	$(PY) benchmarks/montecarlo.py
	$(PY) benchmarks/scaling.py
