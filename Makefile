# Quick start: `make run` (simulated arm) and `make test`. Both create .venv on first use; `run` installs
# what running needs, the test and lint targets add the test extras (pytest, ruff, mypy, stubs).
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
TEST_STAMP := $(VENV)/.installed-test

.PHONY: run test test-slow lint clean

$(STAMP): pyproject.toml
	$(PYTHON) -c 'import sys; sys.exit("plem needs Python >= 3.11, found " + sys.version.split()[0]) if sys.version_info < (3, 11) else None'
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e .
	touch $(STAMP)

$(TEST_STAMP): $(STAMP)
	$(BIN)/pip install --quiet -e '.[test]'
	touch $(TEST_STAMP)

run: $(STAMP)
	$(BIN)/plem launch bus:=mock

# Unit and integration tests on two workers; the end-to-end tests, whose launches run real-time loops, one at a time.
test: $(TEST_STAMP)
	$(BIN)/pytest -q -m "not slow" -n 2 tests/unit tests/integration
	$(BIN)/pytest -q -m "not slow" tests/e2e

lint: $(TEST_STAMP)
	$(BIN)/ruff check src tests benchmarks
	$(BIN)/mypy

test-slow: $(TEST_STAMP)
	$(BIN)/pytest -q -m slow

clean:
	rm -rf $(VENV) build src/*.egg-info
