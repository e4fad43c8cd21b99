# Two commands on a fresh machine: `make demo` and `make test`.
# Each creates .venv on first use and installs what it needs (idempotent: a stamp
# file per extras set is rebuilt only when pyproject.toml changes).
# Any Python >= 3.11 that runs: python3.11 first (what CI and the pinned wheels are
# tested with), then newer ones, then python3. A name on PATH is not enough: pyenv
# puts shims for every version it knows on PATH, and an inactive one fails to run.
PYTHON ?= $(shell for p in python3.11 python3.12 python3.13 python3; do \
	if $$p -c 'import sys; sys.exit(sys.version_info < (3, 11))' >/dev/null 2>&1; then \
	command -v $$p; break; fi; done)
VENV := .venv
PY := $(VENV)/bin/python
export OMP_NUM_THREADS ?= 1
export OPENBLAS_NUM_THREADS ?= 1
export MKL_NUM_THREADS ?= 1
export NUMBA_NUM_THREADS ?= 1

.PHONY: demo test fuzz bench lint clean default-model

$(PY):
	@test -n "$(PYTHON)" || { echo "gradgps needs Python >= 3.11 on PATH (python3.11, python3.12, python3.13 or python3); or set PYTHON=/path/to/python3.11+"; exit 1; }
	@$(PYTHON) -c 'import sys; sys.exit(0 if sys.version_info >= (3, 11) else "gradgps needs Python >= 3.11; found " + sys.version.split()[0] + " ($(PYTHON)); set PYTHON=/path/to/python3.11+")'
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip

$(VENV)/.stamp-demo: pyproject.toml | $(PY)
	$(PY) -m pip install -q -e ".[io,report]"
	touch $@

$(VENV)/.stamp-test: pyproject.toml | $(PY)
	$(PY) -m pip install -q -e ".[io,train,dev,report,onnx,ros,fleet,geo,peers]"
	touch $@ $(VENV)/.stamp-demo

# numba caches compiled kernels next to the sources and checks only the cached function's
# own file, so after a pull or an edit that changes a kernel's callee in another module
# an old compilation of the caller keeps running, silently. Every target that runs the
# kernels clears the caches first whenever a source is newer than the last clearing
# (the first run after it compiles afresh: a minute or two).
KERNEL_SOURCES := $(shell find src -name '*.py')
build/.stamp-kernels: $(KERNEL_SOURCES)
	find src -name '*.nbi' -delete -o -name '*.nbc' -delete
	rm -rf build/numba-boundscheck
	@mkdir -p build && touch $@

demo: $(VENV)/.stamp-demo build/.stamp-kernels
	$(VENV)/bin/gradgps demo

# The suite runs on TEST_WORKERS processes (pytest-xdist), a test module's tests in one of
# them (--dist loadscope: a module's fixtures are built once); 2 fits CI's 2 cores.
test: $(VENV)/.stamp-test build/.stamp-kernels
	$(PY) -m ruff check src tests benchmarks
	$(PY) -m mypy
	$(PY) -m pytest -q -n $(TEST_WORKERS) --dist loadscope
TEST_WORKERS ?= 2

# The long fuzz run (tests/test_fuzz.py): 2,500 cases for each of its 14 tests,
# 35,000 in all; make test runs the same tests with 30 cases each. The compiled
# kernels are built with bounds checks here (NUMBA_BOUNDSCHECK=1, cached apart from
# the normal build, about 25 s the first time): an out-of-bounds index, which a
# normal build reads or writes silently (or ends in SIGSEGV), is an IndexError
# that fails the case and names it.
fuzz: $(VENV)/.stamp-test build/.stamp-kernels
	GRADGPS_FUZZ_EXAMPLES=$(FUZZ_EXAMPLES) NUMBA_BOUNDSCHECK=1 NUMBA_CACHE_DIR=build/numba-boundscheck \
		$(PY) -m pytest -q tests/test_fuzz.py
FUZZ_EXAMPLES ?= 2500

lint: $(VENV)/.stamp-test
	$(PY) -m ruff check src tests benchmarks
	$(PY) -m ruff format --check src tests benchmarks
	$(PY) -m mypy

bench: $(VENV)/.stamp-test build/.stamp-kernels
	$(PY) benchmarks/run_all.py

# The model shipped in the package: the training recipe (src/gradgps/_train/recipe.py:
# simulated drives at 0.5-10 Hz plus the train splits of the real drives in
# ../shared/data, columns withheld at random, dropouts, frozen fixes), fixed
# epochs, so anyone with the data can reproduce it byte for byte on the same processor
# (torch's CPU kernels round differently across processors: docs/model-card.md).
default-model: $(VENV)/.stamp-test build/.stamp-kernels
	$(VENV)/bin/gradgps train --dataset recipe --max-epochs $(DEFAULT_EPOCHS) --time-budget 3600 \
		--members $(DEFAULT_MEMBERS) --jobs $(DEFAULT_JOBS) --confirm-head -o src/gradgps/models/default
DEFAULT_EPOCHS ?= 30
# Networks trained with seeds 0, 1, ... and shipped as one, their mean (docs/model-card.md);
# each with a confirm head, which settles a fix's verdict when the next fix has been read.
DEFAULT_MEMBERS ?= 4
# Members trained at a time, each in its own process on one core: the same weights
# bit for bit whatever the number; four members took 24.5 minutes with 2 on the
# 2-core development machine, against about an hour one at a time.
DEFAULT_JOBS ?= 2

# Everything built: the environment, the caches, the compiled kernels (see above).
clean:
	rm -rf $(VENV) build .pytest_cache .mypy_cache .ruff_cache
	find src -name '*.nbi' -delete -o -name '*.nbc' -delete
