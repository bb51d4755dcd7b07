# beltdyn: `make test` and `make paper` work on a fresh clone with only Python 3.11 and pip.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed-stamp

.PHONY: test test-slow test-all paper bench clean

$(STAMP): pyproject.toml
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	@touch $(STAMP)

test: $(STAMP)
	$(BIN)/python -m pytest -q

test-slow: $(STAMP)
	$(BIN)/python -m pytest -q -m slow

test-all: $(STAMP)
	$(BIN)/python -m pytest -q -m 'slow or not slow'

paper: $(STAMP)
	$(BIN)/beltdyn paper --outdir results/paper --configs configs/paper --force

bench: $(STAMP)
	$(BIN)/python bench/run.py

clean:
	rm -rf results/*.h5 results/paper/*.h5 .pytest_cache
