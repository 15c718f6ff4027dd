# sewmech: two commands set everything up on a fresh machine (Python >= 3.11, pip, make).
#   make demo          virtual environment + install + the main job on the default machine (JB1-3)
#   make test          the whole test suite in the same environment
# Both install the exact versions of requirements.lock (hashes checked), so every machine runs
# what CI ran. The other targets:
#   make test-latest   a separate environment with the newest releases pyproject.toml allows,
#                      and the suite run in it: a break from a new release found on purpose
#   make lock          regenerate requirements.lock from pyproject.toml (uv pip compile), with
#                      the newest releases it allows
#   make bench         the benchmarks, then the table of current figures (printed, and
#                      rewritten at the top of BENCHMARKS.md)
#   make bench-table   the table of current figures from benchmarks/results/*.json (runs nothing)
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
OUT    ?= out/demo
STAMP  := $(VENV)/.installed
LOCK   := requirements.lock
# the environment of `make test-latest`, with its own numba cache: the two environments may run
# different numba releases, and each would otherwise throw the other's compiled kernels away
LATEST := .venv-latest
UV     := uv==0.13.9

.PHONY: demo test test-latest lock bench bench-table install clean

$(STAMP): pyproject.toml $(LOCK)
	@echo "sewmech: creating $(VENV) and installing the locked versions of $(LOCK)"
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --require-hashes --no-deps -r $(LOCK)
	$(BIN)/python -m pip install --quiet --no-deps --no-build-isolation -e .
	$(BIN)/python -m sewmech.engine.warm
	touch $(STAMP)

install: $(STAMP)

demo: $(STAMP)
	$(BIN)/sewmech report jb1-3 --out $(OUT)

# the tests call every kernel: the ones the install leaves to their first use are compiled here
# (a second when they are already compiled), so that no test waits for the compiler
test: $(STAMP)
	$(BIN)/python -m sewmech.engine.warm --all
	$(BIN)/python -m pytest -q

test-latest:
	@echo "sewmech: installing the newest releases pyproject.toml allows into $(LATEST)"
	$(PYTHON) -m venv $(LATEST)
	$(LATEST)/bin/python -m pip install --quiet --upgrade pip
	$(LATEST)/bin/python -m pip install --quiet --upgrade --upgrade-strategy eager -e ".[test,bench,dev]"
	$(LATEST)/bin/python -m pip list --format=freeze > $(LATEST)/versions.txt
	@echo "sewmech: the versions tested are listed in $(LATEST)/versions.txt"
	NUMBA_CACHE_DIR=$(abspath $(LATEST))/numba-cache $(LATEST)/bin/python -m sewmech.engine.warm --all
	NUMBA_CACHE_DIR=$(abspath $(LATEST))/numba-cache $(LATEST)/bin/python -m pytest -q -p no:cacheprovider

# the runtime, test, bench and dev dependencies and the build tools (given on stdin), for every
# Python >= 3.11, with the hashes of every file PyPI has of each version
lock:
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet "$(UV)"
	printf 'setuptools>=77\nwheel\n' | $(BIN)/uv pip compile pyproject.toml - --universal \
	    --python-version 3.11 --extra test --extra bench --extra dev --generate-hashes --upgrade \
	    --quiet -o $(LOCK)

# the table is printed and written even when a benchmark failed (the others' figures are new);
# the exit status is the benchmarks'
bench: $(STAMP)
	$(BIN)/python benchmarks/run_all.py; rc=$$?; \
	    $(BIN)/python benchmarks/table.py --write; exit $$rc

bench-table: $(STAMP)
	$(BIN)/python benchmarks/table.py

clean:
	rm -rf $(VENV) $(LATEST) out .pytest_cache
