# Two entry points: `make demo` (the main job) and `make test` (lint, the documentation site, the suite).
# Both create .venv and install the project into it on first use.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: setup demo test test-slow bench crocoddyl-env hpipm clean

setup: $(STAMP)

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $(STAMP)

demo: setup
	$(BIN)/psdm demo --out demo_report --overwrite

# One BLAS thread per test process: the suite runs one process per core, and each process's BLAS starting a thread
# per core as well oversubscribes the machine.
SUITE_THREADS = OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 MKL_NUM_THREADS=1

test: setup
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	NO_MKDOCS_2_WARNING=1 $(BIN)/python -m mkdocs build --strict --quiet --site-dir site
	$(SUITE_THREADS) $(BIN)/python -m pytest -q -m "not slow" -n auto --maxprocesses 4 --dist loadfile

# The tests marked slow (whole identify/diagnose runs on the virtual and unseen arms, about half an hour on two
# cores): `.ci/nightly` runs this, so a change that breaks one is seen the next day rather than never.
test-slow: setup
	$(SUITE_THREADS) $(BIN)/python -m pytest -q -m slow -n auto --maxprocesses 4 --dist load

bench: setup
	$(BIN)/python -m pip install --quiet -e '.[bench]'
	$(BIN)/python benchmarks/derivation.py
	$(BIN)/python benchmarks/dynamics_speed.py --robots denso
	$(BIN)/python benchmarks/excitation.py
	$(BIN)/python benchmarks/calibration.py
	$(BIN)/python benchmarks/diagnosis.py
	$(BIN)/python benchmarks/real_identification.py

# Crocoddyl (the MPC peer) in an environment of its own, with the Pinocchio its wheel was built for:
#   make crocoddyl-env && .venv/bin/python benchmarks/mpc.py --crocoddyl-python .venv-crocoddyl/bin/python
crocoddyl-env:
	python3 -m venv .venv-crocoddyl
	.venv-crocoddyl/bin/python -m pip install --quiet -e . "crocoddyl==3.1.0" "pin==3.8.0"

# BLASFEO and HPIPM built for this CPU (needs git, cmake and access to GitHub) into psdm's cache folder, where
# trajopt.mpc_rti.compile_rti finds them without PSDM_HPIPM_DIR: the Panda's MPC step 1.3-1.6x faster than on
# CasADi's portable BLASFEO. Another CPU than AVX2+FMA: make hpipm HPIPM_TARGETS="X64_INTEL_SANDY_BRIDGE AVX"
HPIPM_TARGETS ?= X64_INTEL_HASWELL AVX
hpipm: setup
	sh benchmarks/build_hpipm.sh "$$($(BIN)/python -c 'from trajopt.hpipm_c import hpipm_cache_folder as f; print(f())')" $(HPIPM_TARGETS)

clean:
	rm -rf $(VENV) .venv-crocoddyl demo_report .pytest_cache site
