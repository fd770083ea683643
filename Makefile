# Thin wrappers over the `cortex` command. `make demo` and `make test` install
# whatever is missing first (a virtual environment in .venv/).
#
#   make setup           .venv/: the default stack (MPICH wheel from PyPI, serial h5py)
#   make setup-parallel  .venv-mpio/: Debian's MPICH + parallel HDF5, h5py built with MPI
#   make demo            the main job, end to end
#   make test            the whole suite, MPI tests on both stacks
#   make analysis        calibration and Monte-Carlo analysis of a finished store
#   make bench           the benchmarks (JSON on stdout)

PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
PVENV  := .venv-mpio
NP     ?= 2
PYTEST_ARGS ?=

.PHONY: setup setup-parallel demo test test-serial test-mpi test-mpi-parallel bench clean

setup: $(VENV)/.installed

$(VENV)/.installed: pyproject.toml
	@$(PYTHON) -c 'import sys; assert sys.version_info >= (3, 11), "Python >= 3.11 needed"'
	@$(PYTHON) -m venv --help >/dev/null 2>&1 && $(PYTHON) -c 'import ensurepip' 2>/dev/null || \
	  { echo "installing python3-venv (Debian)"; apt-get update -qq && apt-get install -y -qq python3-venv python3-dev; }
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip
	$(BIN)/pip install -q -e '.[mpich,test]'
	@touch $@

setup-parallel: $(PVENV)/.installed

$(PVENV)/.installed: pyproject.toml scripts/setup-parallel.sh
	PYTHON=$(PYTHON) bash scripts/setup-parallel.sh $(PVENV)
	@touch $@

demo: setup
	$(BIN)/cortex geometry --volume 4300 --height 15 14 13 12 11 10

test: test-serial test-mpi test-mpi-parallel

test-serial: setup
	$(BIN)/python -m pytest -q $(PYTEST_ARGS) tests

test-mpi: setup
	$(BIN)/mpiexec -n $(NP) $(BIN)/python -m pytest -q --with-mpi -m mpi -p no:cacheprovider tests

# The parallel-HDF5 stack needs Debian packages (root); where it cannot be
# installed, setup-parallel.sh exits 77 and these tests are skipped, saying so.
test-mpi-parallel:
	@status=0; PYTHON=$(PYTHON) bash scripts/setup-parallel.sh $(PVENV) || status=$$?; \
	if [ $$status = 77 ]; then echo "SKIPPED: parallel-HDF5 MPI tests (stack cannot be installed here)"; \
	elif [ $$status != 0 ]; then exit $$status; \
	else $(PVENV)/bin/with-mpi mpiexec -n $(NP) $(PVENV)/bin/python -m pytest -q --with-mpi -m mpi -p no:cacheprovider tests; fi

bench: setup
	@for b in bench/*.py; do $(BIN)/python $$b; done

clean:
	rm -rf $(VENV) $(PVENV) build *.egg-info
