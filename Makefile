# sphri: `make run` and `make test` are all a newcomer needs.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.sphri-installed
ARGS   ?=

.PHONY: install run lint test test-all docs docs-serve bench profile-tests sweep report ui clean

# Installs only when pyproject.toml changed since the last install (quick otherwise).
# torch is pinned to the CPU build first: an unpinned torch pulls gigabytes of CUDA.
$(STAMP): pyproject.toml setup.py
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q "torch==2.13.0"
	$(BIN)/python -m pip install -q -e ".[dev]"
	$(BIN)/python -m sphri warmup  # numba kernels compiled once here, not in the first job
	@touch $(STAMP)

install: $(STAMP)

run: install          ## the main job on the built-in defaults
	$(BIN)/python -m sphri +robot=reachy layout.res=18 $(ARGS)

lint: install         ## ruff (lint + format check) and mypy on sphri/ and hydra_plugins/ (pyproject.toml)
	$(BIN)/ruff check sphri hydra_plugins tests bench
	$(BIN)/ruff format --check sphri hydra_plugins tests bench
	$(BIN)/mypy

# Tests run on every core (pytest-xdist); a test module stays on one worker, so its
# module fixtures are built once. `make test WORKERS=0` runs them in one process.
WORKERS ?= auto
test: lint            ## lint, then the test suite without slow tests
	$(BIN)/python -m pytest -m "not slow" -q -n $(WORKERS) --dist loadscope --no-loadscope-reorder $(ARGS)

# The documentation site (mkdocs.yml, docs/): `make test` builds it too (tests/test_docs.py, --strict).
docs: install         ## the documentation site -> site/ (strict: a broken link or reference fails)
	$(BIN)/mkdocs build --strict -d site

docs-serve: install   ## the documentation site on http://127.0.0.1:8000, rebuilt on every edit
	$(BIN)/mkdocs serve -a 127.0.0.1:8000

# The cluster launchers (Ray, SLURM) are tested by test-all only: installed once,
# again only when pyproject.toml (or the base install) changed.
CLUSTER_STAMP := $(VENV)/.sphri-cluster-installed
$(CLUSTER_STAMP): pyproject.toml $(STAMP)
	$(BIN)/python -m pip install -q -e ".[dev,cluster]"
	@touch $(CLUSTER_STAMP)

test-all: install $(CLUSTER_STAMP)  ## every test, slow ones, cluster launchers and deep property tests included
	SPHRI_DEEP_TESTS=1 $(BIN)/python -m pytest -q -n $(WORKERS) --dist loadscope --no-loadscope-reorder $(ARGS)

bench: install        ## benchmarks -> outputs/bench/*.json, summary.md, plots
	$(BIN)/python bench/run_all.py $(ARGS)

profile-tests: install  ## the suite under py-spy: its CPU time by kind of work, process, test, origin -> outputs/bench/suite_profile.md
	$(BIN)/python -m pip install -q "py-spy>=0.4"
	$(BIN)/python bench/profile_suite.py $(ARGS)

sweep: install        ## the resolution sweep (Random Forest, 50 resolutions)
	$(BIN)/python -m sphri -m +experiment=resolution_sweep model=rf hydra.sweep.dir=outputs/sweeps/resolution_rf $(ARGS)
	$(BIN)/python -m sphri report outputs/sweeps/resolution_rf

ui: install           ## MLflow UI on http://127.0.0.1:5000
	$(BIN)/mlflow ui --backend-store-uri sqlite:///$(CURDIR)/outputs/mlflow.db --host 127.0.0.1 --port 5000

clean:                ## remove outputs (runs, cache, MLflow store) and test caches
	rm -rf outputs site .pytest_cache .hypothesis
