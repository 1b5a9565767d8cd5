# panostereo: two commands do everything on a fresh machine with python3 and make.
#   make demo   build .venv, install, run the whole network on localhost
#   make test   build .venv, install test needs (system ones too when root), run pytest
#   make install  the runtime only (no test or lint tools): what a camera host or a manager host needs
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
RUNTIME_STAMP := $(VENV)/.runtime
DEMO_ARGS ?=

.PHONY: all demo test check bench .venv install clean system-deps

all: test

$(STAMP): pyproject.toml
	$(PY) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test,dev]'
	touch $(STAMP) $(RUNTIME_STAMP)

.venv: $(STAMP)

$(RUNTIME_STAMP): pyproject.toml
	$(PY) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e .
	touch $(RUNTIME_STAMP)

install: $(RUNTIME_STAMP)

demo: $(STAMP)
	$(BIN)/panostereo demo $(DEMO_ARGS)

system-deps:
	@bash tests/system_deps.sh

# The integration tests run one after another on one worker, the unit and property tests (and the bad-input rows)
# on the others beside them (tests/conftest.py); PYTEST_ARGS="-n 0" runs everything in one process.
test: $(STAMP) system-deps
	$(BIN)/python -m pytest -n auto --dist loadgroup $(PYTEST_ARGS)

check: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/mypy

bench: $(STAMP)
	$(BIN)/python -m benchmarks.run_all

clean:
	rm -rf $(VENV) .pytest_cache .mypy_cache .ruff_cache build *.egg-info
