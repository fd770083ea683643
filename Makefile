# Thin wrappers over the `cortex` command. `make demo` and `make test` install
# whatever is missing first (a virtual environment in .venv/).
#
#   make setup           .venv/: the default stack (MPICH wheel from PyPI, serial h5py), the solver compiled
#   make setup-parallel  .venv-mpio/: Debian's MPICH + parallel HDF5, h5py built with MPI
#   make demo            the main job, end to end
#   make test            the type checker (beside the solver's compilation), then the whole suite, MPI tests on both stacks
#   make analysis        calibration and Monte-Carlo analysis of a finished store
#   make calibration     rebuild the shipped calibration (analysis/calibration/data/calibration.json)
#   make viscoelastic-table  rebuild the shipped viscoelastic table (analysis/calibration/data/viscoelastic_table.json)
#   make ramp-table      rebuild the shipped shell ramp table (analysis/calibration/data/shell_ramp_table.json)
#   make powerlaw-table  rebuild the shipped power-law ramp and hold table (analysis/calibration/data/powerlaw_table.json)
#   make protocol-map    the protocol's bias map (results/protocol-map/: JSON table and figures)
#   make tension-bias    the shell's reading of power-law ramps (results/tension-bias.md: the table)
#   make bench           the quick benchmarks (BENCH_QUICK: each under about a minute; JSON on stdout)
#   make bench-full      every script in bench/; the others take minutes to an hour and more each
#                        (the solver-forward round trip and error sources, the Monte-Carlo study by
#                        both methods, a million no-op tasks, the campaign's throughput and scaling,
#                        the solvers' speed and mesh convergence, the viscous solver, height coverage)

PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
PVENV  := .venv-mpio
NP     ?= 2
PYTEST_ARGS ?=

.PHONY: setup setup-parallel setup-slurm demo test typecheck test-serial test-mpi test-mpi-parallel bench bench-full clean

setup: $(VENV)/.installed

$(VENV)/.packages: pyproject.toml
	@$(PYTHON) -c 'import sys; assert sys.version_info >= (3, 11), "Python >= 3.11 needed"'
	@$(PYTHON) -m venv --help >/dev/null 2>&1 && $(PYTHON) -c 'import ensurepip' 2>/dev/null || \
	  { [ "$$(id -u)" = 0 ] || { echo "setup: $(PYTHON) cannot make a venv: apt-get install python3-venv (as root)"; exit 1; }; \
	    echo "setup: installing python3-venv (Debian)"; export DEBIAN_FRONTEND=noninteractive; \
	    apt-get update -qq && apt-get install -y -qq --no-install-recommends python3-venv >/dev/null; }
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip
	$(BIN)/pip install -q -e '.[mpich,test]'
	@touch $@

$(VENV)/.installed: $(VENV)/.packages
	@echo "setup: compiling the fast solver once (numba's on-disk cache, about a minute; later processes and MPI ranks load it)"
	@$(BIN)/cortex compress --h0 12 --bulk 25 --shear 10 --tension 1 >/dev/null
	@touch $@

# scripts/setup-parallel.sh is a fast no-op once done; it exits 77 where the
# stack cannot be installed (Debian packages missing and not root).
SETUP_PARALLEL = status=0; PYTHON=$(PYTHON) bash scripts/setup-parallel.sh $(PVENV) || status=$$?; \
	if [ $$status = 77 ]; then echo "SKIPPED: parallel-HDF5 stack (cannot be installed here)"; \
	elif [ $$status != 0 ]; then exit $$status; fi

setup-parallel:
	@$(SETUP_PARALLEL)

demo: setup
	$(BIN)/cortex geometry --volume 4300 --height 15 14 13 12 11 10
	$(BIN)/mpiexec -n $(NP) $(BIN)/cortex campaign run campaigns/demo.toml --store results/demo.h5 --new || [ $$? = 1 ]
	$(BIN)/cortex campaign status results/demo.h5
	$(BIN)/cortex analysis calibrate results/demo.h5 --out results/demo-analysis --partial
	@echo "demo store: results/demo.h5 (cortex campaign status results/demo.h5); report: results/demo-analysis/report.md"
	@# a small synthetic experiment (12 cells, the solver as forward model, errors on; kept once made),
	@# analysed with the calibration shipped in the package: nu per frequency with 95 % intervals; read as
	@# its file says it was made (frequency-domain: the relaxed state; a measured one with its own waits)
	@[ -e results/demo-experiment/experiment.h5 ] || $(BIN)/cortex afm synth --cells 12 --seed 7 --out results/demo-experiment
	$(BIN)/cortex afm analyze results/demo-experiment --out results/demo-experiment/analysis
	@grep -m1 '^\*\*Trend' results/demo-experiment/analysis/report.md
	@sed -n '/^Median/,/^Each cell/p' results/demo-experiment/analysis/report.md
	@echo "true medians: results/demo-experiment/truth.json; per cell: results/demo-experiment/analysis/cells.csv"

# The type checker beside the solver's one compilation (one core each) and SLURM's packages; then
# the suites, and beside them the parallel stack built (Debian's packages, pip's downloads, h5py
# compiled) and its own tests run (in a session of their own, so that an interrupt ends them
# too); their log follows the suites'. Both exit statuses count.
test:
	@$(MAKE) --no-print-directory -j3 typecheck setup setup-slurm
	@log=$$(mktemp); setsid $(MAKE) --no-print-directory setup-parallel test-mpi-parallel >$$log 2>&1 & side=$$!; \
	trap 'kill -- -$$side 2>/dev/null; exit 130' INT TERM; \
	s=0; $(MAKE) --no-print-directory test-serial test-mpi || s=$$?; \
	p=0; wait $$side || p=$$?; echo "+ make setup-parallel test-mpi-parallel   (beside the passes above)"; \
	cat $$log; rm -f $$log; [ $$s = 0 ] || exit $$s; exit $$p

# The type checker over the typed packages (pyproject.toml, [tool.mypy]).
typecheck: $(VENV)/.packages
	$(BIN)/python -m mypy

# The serial suite in two passes at once (docs/testing.md), each printing its 20 slowest tests
# (CI gives the suite 20 minutes): the tests marked `serial` (SLURM's: the CPU 22 % busy) and
# beside them the others on TEST_WORKERS processes (pytest-xdist; a file's tests stay on one worker, so its
# module fixtures are built once; each on one BLAS thread, as a campaign rank: two workers' BLAS
# threads would wait on each other's cores). The serial pass's output follows the other's. A
# pass's exit status 5 ("no tests collected": PYTEST_ARGS chose none of its tests) is not a
# failure unless the other pass collected none either.
TEST_WORKERS ?= 2
SERIAL_PASS = $(BIN)/python -m pytest -q --durations=20 --serial only $(PYTEST_ARGS) tests
test-serial: setup setup-slurm
	@a=0; b=0; log=$$(mktemp); \
	$(SERIAL_PASS) >$$log 2>&1 & serial=$$!; \
	trap 'kill $$serial 2>/dev/null; exit 130' INT TERM; \
	set -x; \
	OPENBLAS_NUM_THREADS=1 $(BIN)/python -m pytest -q --durations=20 -n $(TEST_WORKERS) --dist loadfile --serial skip $(PYTEST_ARGS) tests || a=$$?; \
	{ set +x; } 2>/dev/null; \
	wait $$serial || b=$$?; \
	echo "+ $(SERIAL_PASS)   (beside the pass above)"; \
	cat $$log; rm -f $$log; \
	for s in $$a $$b; do [ $$s = 0 ] || [ $$s = 5 ] || exit $$s; done; \
	[ $$a$$b != 55 ] || { echo "test-serial: no tests collected"; exit 5; }

# SLURM for tests/test_slurm.py (which skips itself, saying why, where the script exits 77).
setup-slurm:
	@bash scripts/setup-slurm.sh install || [ $$? = 77 ]

# MPI runs: each rank runs pytest; exit status 5 ("no tests collected": no
# MPI tests in the selection) is not a failure, any other non-zero status is.
# MPIEXEC_TIMEOUT (s) ends a deadlocked run instead of hanging CI.
MPI_TIMEOUT ?= 900
mpi_pytest = MPIEXEC_TIMEOUT=$(MPI_TIMEOUT) $(1) -n $(NP) \
	sh -c '"$$@" || { s=$$?; [ $$s = 5 ] && echo "no MPI tests collected" || exit $$s; }' rank \
	$(2) -m pytest -q --with-mpi -m mpi -p no:cacheprovider $(PYTEST_ARGS) tests

test-mpi: setup
	$(call mpi_pytest,$(BIN)/mpiexec,$(BIN)/python)

# The same on the parallel-HDF5 stack, plus (in pytest's processes, not as ranks: they start
# mpiexec themselves; on TEST_WORKERS processes, a file each) its doctor and the store's two
# write paths compared; where it cannot be installed, this says SKIPPED and passes.
test-mpi-parallel:
	@$(SETUP_PARALLEL); \
	if [ $$status = 0 ]; then set -x; \
	  OPENBLAS_NUM_THREADS=1 $(PVENV)/bin/with-mpi $(PVENV)/bin/python -m pytest -q -p no:cacheprovider -n $(TEST_WORKERS) --dist loadfile $(PYTEST_ARGS) \
	    tests/test_stack.py tests/test_campaign_writepath.py tests/test_full_disk.py && \
	  $(call mpi_pytest,$(PVENV)/bin/with-mpi mpiexec,$(PVENV)/bin/python); fi

# Calibration laws, reconstruction check, Monte-Carlo study and report of a
# finished store: make analysis [STORE=results/paper.h5] [OUT=results/analysis]
# [DATA=experiment.h5] (DATA: also the measured cells, with this law-only calibration: --no-phase).
.PHONY: analysis
analysis: setup
	$(BIN)/cortex analysis calibrate $(or $(STORE),results/paper.h5) --out $(or $(OUT),results/analysis)
	$(if $(DATA),$(BIN)/cortex afm analyze $(DATA) --calibration $(or $(OUT),results/analysis)/calibration.json --no-phase --out $(or $(OUT),results/analysis)/afm)
	@echo "report: $(or $(OUT),results/analysis)/report.md"

# The shipped calibration: the emulator campaign and the paper campaign under
# mpiexec (about 4-5 min on 2 shared cores; reruns resume), then one file with
# both and their provenance ($(CALIBRATION)/calibration.json).
CALIBRATION := analysis/calibration/data
.PHONY: calibration
calibration: setup
	$(BIN)/mpiexec -n $(NP) $(BIN)/cortex campaign run campaigns/emulator.toml --store results/emulator.h5 || [ $$? = 1 ]  # a failed point is solved again by build-calibration
	$(BIN)/mpiexec -n $(NP) $(BIN)/cortex campaign run campaigns/paper.toml --store results/paper.h5
	$(BIN)/cortex analysis build-calibration --emulator-store results/emulator.h5 --law-store results/paper.h5 --out $(CALIBRATION)

# The shipped viscoelastic table: its campaign under mpiexec (1440 nodes; see
# docs/performance.md for its time; reruns resume), then the table from the store
# (results/viscoelastic-table/), copied into the package.
.PHONY: viscoelastic-table
viscoelastic-table: setup
	$(BIN)/mpiexec -n $(NP) $(BIN)/cortex campaign run campaigns/viscoelastic.toml --store results/viscoelastic.h5
	$(BIN)/cortex analysis build-viscoelastic-table results/viscoelastic.h5 --out results/viscoelastic-table
	cp results/viscoelastic-table/viscoelastic_table.json $(CALIBRATION)/viscoelastic_table.json

# The shipped shell ramp table: its campaign under mpiexec (540 nodes; see
# docs/performance.md for its time; reruns resume), then the table from the store
# (results/ramp-table/), copied into the package.
.PHONY: ramp-table
ramp-table: setup
	$(BIN)/mpiexec -n $(NP) $(BIN)/cortex campaign run campaigns/ramp.toml --store results/ramp.h5
	$(BIN)/cortex analysis build-ramp-table results/ramp.h5 --out results/ramp-table
	cp results/ramp-table/shell_ramp_table.json $(CALIBRATION)/shell_ramp_table.json

# The power-law ramp and hold table (docs/tension-power-law.md): its campaign under mpiexec (8400
# nodes, about 20 min on 2 ranks; reruns resume), then the table from the store, copied into the package.
.PHONY: powerlaw-table
powerlaw-table: setup
	$(BIN)/mpiexec -n $(NP) $(BIN)/cortex campaign run campaigns/powerlaw-table.toml --store results/powerlaw-table.h5
	$(BIN)/cortex analysis build-powerlaw-table results/powerlaw-table.h5 --out results/powerlaw-table
	cp results/powerlaw-table/powerlaw_table.json $(CALIBRATION)/powerlaw_table.json

# The protocol's bias map (SPEC 12, docs/studies/protocol-bias.md): its campaign under mpiexec (see
# docs/performance.md for its time; reruns resume), then the JSON table and figures from the store.
.PHONY: protocol-map
protocol-map: setup
	$(BIN)/mpiexec -n $(NP) $(BIN)/cortex campaign run campaigns/protocol.toml --store results/protocol.h5 || [ $$? = 1 ]
	$(BIN)/cortex analysis build-protocol-map results/protocol.h5 --out results/protocol-map

# The elastic shell's reading of power-law ramps (docs/tension.md, docs/studies/tension-bias.md): its
# campaign under mpiexec (the kind is a study's, so the repository root goes on PYTHONPATH; about 5 min
# on 2 ranks; reruns resume), then the table from the store.
.PHONY: tension-bias
tension-bias: setup
	PYTHONPATH=$(CURDIR) $(BIN)/mpiexec -n $(NP) $(BIN)/cortex campaign run campaigns/tension-bias.toml --store results/tension-bias.h5 || [ $$? = 1 ]
	PYTHONPATH=$(CURDIR) $(BIN)/python -m studies.shell_reading_bias results/tension-bias.h5 > results/tension-bias.md

# Benchmarks: one JSON object each on stdout; every script runs as `python bench/X.py` (no script
# is named like a package: tests/test_bench_scripts.py) and the target fails if one did.
# BENCH_QUICK: under about a minute of one core each (CPU time with /usr/bin/time on the shared
# 2-core machine: emulator 3 s, reconstruction 3 s, offgrid_invert 9 s, afm 11 s, calibrate_invert 34 s;
# geometry 13 s wall, mostly compiling; trials is sized for seconds). reconstruction needs
# results/paper.h5 (make calibration).
BENCH_QUICK ?= geometry emulator reconstruction offgrid_invert afm trials calibrate_invert
run_benches = status=0; for b in $(1); do $(BIN)/python $$b || { echo "bench: $$b failed" >&2; status=1; }; done; \
	exit $$status

bench: setup
	@$(call run_benches,$(BENCH_QUICK:%=bench/%.py))

bench-full: setup
	@$(call run_benches,bench/*.py)

clean:
	rm -rf $(VENV) $(PVENV) build *.egg-info solver/__pycache__/numba-*
