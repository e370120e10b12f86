# Quick start: `make run` (simulated arm) and `make test`. Both create .venv on first use and compile plem's core
# (gcc and the Python headers: Debian/Ubuntu `build-essential python3-dev`); `run` installs what running needs, the
# test and lint targets add the test extras (pytest, ruff, mypy, stubs).
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
TEST_STAMP := $(VENV)/.installed-test
CORE_SOURCES := $(wildcard src/plem/control/csrc/*.c src/plem/control/csrc/*.h)
SOEM := third_party/soem
SOEM_SOURCES := $(wildcard $(SOEM)/soem/*.c) $(SOEM)/osal/linux/osal.c $(wildcard $(SOEM)/oshw/linux/*.c)
SOEM_INCLUDES := $(SOEM)/soem $(SOEM)/osal $(SOEM)/osal/linux $(SOEM)/oshw/linux
SANITIZE_COMMON := -fno-sanitize-recover=all -fno-omit-frame-pointer -O1 -g -fPIC -D_GNU_SOURCE
SANITIZE := -fsanitize=address,undefined $(SANITIZE_COMMON)
# SOEM (unmodified) shifts 1 into the sign bit (1 << 31 in ethercatmain.c): it gets AddressSanitizer only.
SOEM_SANITIZE := -fsanitize=address $(SANITIZE_COMMON)
CORE_FLAGS := -std=c11 -Wall -Wextra -Werror -Wshadow -Wstrict-prototypes -shared -DPLEM_SOEM_VERSION='"v1.4.0"' \
	$(addprefix -isystem,$(SOEM_INCLUDES))
SANITIZED := build/sanitized
# The core's tests, which call it through its Python face.
CORE_TESTS := tests/unit/test_core_properties.py tests/unit/test_cia402.py tests/unit/test_polynomial.py \
	tests/integration/test_mock_bus.py tests/integration/test_runtime.py tests/integration/test_core_thread.py \
	tests/integration/test_core_master.py tests/integration/test_streaming.py tests/integration/test_reactions.py

.PHONY: run test test-slow test-sanitized lint clean

$(STAMP): pyproject.toml setup.py $(CORE_SOURCES) $(SOEM_SOURCES)
	$(PYTHON) -c 'import sys; sys.exit("plem needs Python >= 3.11, found " + sys.version.split()[0]) if sys.version_info < (3, 11) else None'
	@command -v gcc >/dev/null || { echo "plem compiles its core with gcc: install it (Debian/Ubuntu: sudo apt install build-essential python3-dev)"; exit 1; }
	@$(PYTHON) -c 'import os, sys, sysconfig; h = os.path.join(sysconfig.get_paths()["include"], "Python.h"); os.path.exists(h) or sys.exit("plem compiles its core against the Python headers, and " + h + " is missing: install them (Debian/Ubuntu: sudo apt install python3-dev)")'
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
	$(BIN)/pytest -q -m "not slow" -n 2 --durations=10 tests/unit tests/integration
	$(BIN)/pytest -q -m "not slow" --durations=20 tests/e2e

lint: $(TEST_STAMP)
	$(BIN)/ruff check src tests benchmarks
	$(BIN)/mypy

test-slow: $(TEST_STAMP)
	$(BIN)/pytest -q -m slow

# The core built with AddressSanitizer and UndefinedBehaviorSanitizer (any finding aborts), in a copy of the package,
# running the core's tests; the interpreter itself is not instrumented, so the ASan runtime is preloaded, and the C++
# runtime with it: ASan finds the real __cxa_throw only in libraries loaded before it (pinocchio's bindings throw).
SANITIZE_PRELOAD = LD_PRELOAD="$$(gcc -print-file-name=libasan.so) $$(gcc -print-file-name=libstdc++.so.6)" \
	ASAN_OPTIONS=detect_leaks=0
test-sanitized: $(TEST_STAMP)
	rm -rf $(SANITIZED) && mkdir -p $(SANITIZED)
	cp -r src/plem $(SANITIZED)/plem && rm -f $(SANITIZED)/plem/control/_core*.so
	mkdir -p $(SANITIZED)/soem && cd $(SANITIZED)/soem && \
		gcc $(SOEM_SANITIZE) $(addprefix -I$(CURDIR)/,$(SOEM_INCLUDES)) -c $(addprefix $(CURDIR)/,$(SOEM_SOURCES))
	gcc $(SANITIZE) $(CORE_FLAGS) \
		-I"$$($(BIN)/python -c 'import sysconfig; print(sysconfig.get_paths()["include"])')" \
		src/plem/control/csrc/*.c $(SANITIZED)/soem/*.o -lm -lpthread -lrt \
		-o $(SANITIZED)/plem/control/_core$$($(BIN)/python -c 'import sysconfig; print(sysconfig.get_config_var("EXT_SUFFIX"))')
	$(SANITIZE_PRELOAD) PYTHONPATH=$(SANITIZED) \
		$(BIN)/python -c 'import plem.control._core as c, sys; sys.exit(0 if "$(SANITIZED)" in c.__file__ else "not the sanitized core: " + c.__file__)'
	$(SANITIZE_PRELOAD) PYTHONPATH=$(SANITIZED) \
		$(BIN)/pytest -q -p no:cacheprovider $(CORE_TESTS)

clean:
	rm -rf $(VENV) build src/*.egg-info
