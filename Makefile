# safecase: `make certify` and `make test` each build .venv from a fresh clone when it is
# missing or stale (requirements.lock or pyproject.toml changed), then run. Python 3.10, 3.11
# and 3.12 are supported from the one lock: `make test PYTHON=/path/to/python3.12
# VENV=.nox/tests-3.12`, or `make test-all-pythons` (nox; docs/python-versions.md).
SHELL := /bin/bash
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.safecase-installed
# the acoustic direction-of-arrival oracle, built from source beside the lock (SR-ACU-2)
ORACLE := $(VENV)/.acoustic-oracle
ORACLE_LOG := out/acoustic-oracle.log
TEST_OUT := out/test-evidence
# extra pytest arguments for `make pytest`, e.g. PYTEST_ARGS='-x -k stopping'
PYTEST_ARGS ?=
# pytest-xdist workers for `make test` (one per core; PYTEST_WORKERS=0 runs the suite in one
# process); the evidence of every worker lands in the one bundle (SR-EVD-10)
PYTEST_WORKERS ?= auto
# uv resolves one lock for all supported Pythons (environment markers); only `make lock` uses it
UV_VERSION := 0.13.9

.PHONY: all test certify certify-full lint typecheck pytest venv lock clean help mutation test-all-pythons \
	acoustic-oracle

help:
	@echo "make certify   run the whole certification suite, write out/certification/<stamp>/"
	@echo "make certify-full  the same with the long campaigns at full size (over an hour)"
	@echo "make test      ruff + import-linter + mypy --strict + pytest (ci profile), evidence in $(TEST_OUT)/"
	@echo "make lock      re-resolve requirements.lock (Python 3.10-3.12) from pyproject.toml (network)"
	@echo "make test-all-pythons  make test on Python 3.10, 3.11, 3.12 (nox; venvs in .nox/)"
	@echo "make mutation  mutation-test safety/ and the per-cycle stages, results in safety/mutation/"
	@echo "make acoustic-oracle  build pyroomacoustics into .venv (the DOA oracle; a C++ compiler)"

# The wheels install with --no-compile: Python compiles what is imported on first import, and
# byte-compiling every module of every wheel up front took half the install (56 of 106 CPU s).
$(STAMP): requirements.lock pyproject.toml
	@$(PYTHON) -c 'import sys; sys.exit(0 if (3, 10) <= sys.version_info[:2] <= (3, 12) else \
	  "safecase needs Python 3.10, 3.11 or 3.12; found " + sys.version.split()[0] + " at $(PYTHON)")'
	rm -rf $(VENV)
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --disable-pip-version-check \
	  $$(grep -E '^(pip|setuptools|wheel)==' requirements.lock)
	$(BIN)/python -m pip install --quiet --disable-pip-version-check --no-deps --no-compile \
	  -r requirements.lock
	$(BIN)/python -m pip install --quiet --disable-pip-version-check --no-deps \
	  --no-build-isolation -e .
	$(BIN)/python -m pip check
	touch $(STAMP)

venv: $(STAMP)

certify: $(STAMP) $(ORACLE)
	MPLBACKEND=Agg $(BIN)/safecase certify $(if $(CONFIG),--config $(CONFIG))

# certify with the long campaigns at full size (docs/findings/README.md): over an hour on 2 cores
certify-full: $(STAMP) $(ORACLE)
	MPLBACKEND=Agg $(BIN)/safecase certify --profile certify-full $(if $(CONFIG),--config $(CONFIG))

lint: $(STAMP)
	$(BIN)/ruff check pipeline safety properties evidence tests
	$(BIN)/ruff format --check pipeline safety properties evidence tests
	$(BIN)/lint-imports

typecheck: $(STAMP)
	$(BIN)/mypy

pytest: $(STAMP)
	rm -rf $(TEST_OUT) && mkdir -p $(TEST_OUT)
	MPLBACKEND=Agg $(BIN)/python -m pytest -q -ra --hypothesis-profile=ci \
	  -n $(PYTEST_WORKERS) --dist loadfile --safecase-out=$(TEST_OUT) --safecase-enforce \
	  --benchmark-min-rounds=5 --benchmark-max-time=0.2 --benchmark-warmup=off \
	  --benchmark-json=$(TEST_OUT)/benchmarks.json $(PYTEST_ARGS)

# The oracle builds (about 100 s of one core) while ruff, import-linter and mypy run on the other.
test: $(STAMP)
	@$(MAKE) --no-print-directory $(ORACLE) & oracle=$$!; \
	  $(MAKE) --no-print-directory lint typecheck; status=$$?; \
	  wait $$oracle; [ $$status -eq 0 ] && $(MAKE) --no-print-directory pytest

# Mutation testing (SR-EVD-5, SR-EVD-6): each module against the tests that claim it, one module
# at a time at the lowest priority, 2 mutants at once; only modules whose source or selected
# tests changed are re-run. Results: safety/mutation/<module>.json (commit them); scratch copy
# and logs in out/mutation/. Cold: several hours on 2 cores (docs/findings/mutation.md);
# MUTATION_ONLY=regex limits it to the matching module paths.
mutation: $(STAMP)
	nice -n 19 $(BIN)/python -m evidence.mutation_run run --jobs 2 \
	  $(if $(MUTATION_ONLY),--only '$(MUTATION_ONLY)')
	$(BIN)/python -m evidence.mutation_run status

# The acoustic direction-of-arrival oracle (SR-ACU-2): pyroomacoustics has no wheels, so pip builds
# it from source (a C++ compiler and network; about 100 s). `make test` and `make certify` try it
# once per .venv and go on without it when the build fails: its test is then skipped, naming
# $(ORACLE_LOG). `make acoustic-oracle` builds it again and fails loudly.
$(ORACLE): $(STAMP)
	@mkdir -p $(dir $(ORACLE_LOG))
	@if $(BIN)/python -m pip install --quiet --disable-pip-version-check -c requirements.lock \
	    'pyroomacoustics==0.8.4' > $(ORACLE_LOG) 2>&1; then \
	  echo "built pyroomacoustics, the acoustic DOA oracle (SR-ACU-2)"; echo built > $(ORACLE); \
	else \
	  echo "could not build pyroomacoustics (the acoustic DOA oracle): its cross-check is skipped;" \
	    "see $(ORACLE_LOG), then make acoustic-oracle"; echo "failed: $(ORACLE_LOG)" > $(ORACLE); \
	fi

acoustic-oracle: $(STAMP)
	rm -f $(ORACLE)
	$(BIN)/python -m pip install --quiet --disable-pip-version-check -c requirements.lock \
	  'pyroomacoustics==0.8.4'
	echo built > $(ORACLE)

# One lock for Python 3.10-3.12: uv's universal resolution keeps the current pins where they
# fit and forks a package by environment marker only where a version drops a Python; then every
# pin is checked to have a wheel for each of the three (nox -s wheels).
lock:
	rm -rf /tmp/safecase-lock && $(PYTHON) -m venv /tmp/safecase-lock
	/tmp/safecase-lock/bin/pip install --quiet uv==$(UV_VERSION) 'nox>=2025.10'
	printf 'pip\nsetuptools\nwheel\n' > /tmp/safecase-lock/tools.in
	/tmp/safecase-lock/bin/uv pip compile pyproject.toml /tmp/safecase-lock/tools.in --extra dev \
	  --universal --python-version 3.10 --no-python-downloads --no-annotate \
	  --custom-compile-command 'make lock' -o requirements.lock
	/tmp/safecase-lock/bin/nox -s wheels

# `make test` on each supported Python, one after the other (about 10 min each on 2 cores).
test-all-pythons: $(STAMP)
	$(BIN)/nox -s tests-3.10 tests-3.11 tests-3.12

clean:
	rm -rf $(VENV) out
