# beltdyn: `make test` and `make paper` work on a fresh clone with only Python 3.11 and pip.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed-stamp

.PHONY: test test-slow test-all paper bench bench-compare bench-interleave trade clean

$(STAMP): pyproject.toml
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	@$(BIN)/python -m compileall -q beltdyn  # the bytecode a pip install writes (PYTHONDONTWRITEBYTECODE may be set)
	@echo "compiling the transient kernels once (numba cache: about 20 s on an idle machine, minutes on a busy one)"
	$(BIN)/python -c "from beltdyn.pipeline import warm_up; warm_up()"
	@touch $(STAMP)

test: $(STAMP)
	$(BIN)/python -m pytest -q

test-slow: $(STAMP)
	$(BIN)/python -m pytest -q -m slow || test $$? -eq 5  # exit 5: no test selected (none marked slow)

test-all: $(STAMP)
	$(BIN)/python -m pytest -q -m 'slow or not slow'

paper: $(STAMP)
	$(BIN)/beltdyn paper --outdir results/paper --configs configs/paper --force
	@echo "Paper Fig. 3b as data: natural frequencies against belt tension, 100 to 600 N"
	$(BIN)/beltdyn sweep configs/paper/bench_T200.toml --param tension.target=100:600:26 --modes 14 \
		-o results/paper/fig3b_tension_sweep.h5 --force
	@echo "Paper Table 2 as data: the influence of EI from 0.02 to 100 N m^2 (T = 200 N)"
	$(BIN)/beltdyn sweep configs/paper/bench_T200.toml --param belt.EI=0.02:100:9:log --modes 12 \
		-o results/paper/ei_sweep.h5 --force
	@echo "Paper Table 1, experimental column: EI and the mass per length identified (beltdyn fit; reference = the paper's theoretical column)"
	$(BIN)/beltdyn fit configs/paper/bench_T200.toml --measured configs/paper/table1_measured.csv \
		--param belt.EI --param belt.mass_per_length -o results/paper/fit_table1.h5 \
		--write-config results/paper/bench_T200_fitted.toml --force
	@echo "Paper Figs. 3b (with Table 1's measured points) and 4, the fit (beltdyn plot):"
	$(BIN)/beltdyn plot results/paper/fig3b_tension_sweep.h5 sweep --measured configs/paper/table1_measured.csv \
		-o results/paper/fig3b.png
	$(BIN)/beltdyn plot results/paper/fit_table1.h5 fit -o results/paper/fit_table1.png
	$(BIN)/beltdyn plot results/paper/bench_T200.h5 modes --modes 1-8 -o results/paper/fig4_modes.png
	@echo "The drive report of the paper bench (beltdyn report):"
	$(BIN)/beltdyn report results/paper/bench_T200.h5 -o results/paper/report.html

trade: $(STAMP)
	$(BIN)/python bench/trade.py README.md

bench: $(STAMP)
	@$(BIN)/python -m compileall -q beltdyn  # bytecode of the current sources, as an installed package has
	$(BIN)/python bench/run.py

# the same benchmarks of another commit and of this tree, side by side: make bench-compare BASE=<rev>
bench-compare: $(STAMP)
	$(BIN)/python bench/compare.py $(BASE)

# the speed clause's in-process rows of another commit and of this tree, taking turns: make bench-interleave BASE=<rev>
bench-interleave: $(STAMP)
	$(BIN)/python bench/interleave.py $(BASE) $(ROUNDS)

clean:
	rm -rf results/*.h5 results/*.h5.parts results/paper/*.h5 results/paper/*.h5.parts .pytest_cache
