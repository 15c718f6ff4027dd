# sewmech: two commands set everything up on a fresh machine (Python >= 3.11, pip, make).
#   make demo   virtual environment + install + the main job on the default machine (JB1-3)
#   make test   the whole test suite in the same environment
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
OUT    ?= out/demo
STAMP  := $(VENV)/.installed

.PHONY: demo test bench install clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e ".[test]"
	$(BIN)/python -m sewmech.engine.warm   # compile the kernels now, not on the first command
	touch $(STAMP)

install: $(STAMP)

demo: $(STAMP)
	$(BIN)/sewmech report jb1-3 --out $(OUT)

test: $(STAMP)
	$(BIN)/python -m pytest -q

bench: $(STAMP)
	$(BIN)/python -m pip install --quiet -e ".[test,bench]"
	$(BIN)/python benchmarks/run_all.py

clean:
	rm -rf $(VENV) out .pytest_cache
