# irlsim developer interface. `make demo` and `make test` are all a newcomer needs.
PY      ?= python3.11
VENV    ?= .venv
BIN     := $(VENV)/bin
IRLSIM  := $(BIN)/irlsim
PRESET  ?= default
DATA    ?= data/$(PRESET)
RUNS    ?= runs/$(PRESET)
SEED    ?= 0

.PHONY: setup net test test-slow demo collect train train-stage1 train-stage2 evaluate drive dagger bench bench-growth transfer styles recipe rounds sweep lint docs import-graph clean

$(BIN)/.installed: pyproject.toml
	@command -v $(PY) >/dev/null || { echo "error: $(PY) not found; install Python 3.11 or run 'make PY=python3 ...'"; exit 1; }
	$(PY) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip
	# torch first: the pinned CPU build; a bare 'torch' would pull a multi-GB CUDA build.
	$(BIN)/pip install -q torch==2.13.0
	$(BIN)/pip install -q -e '.[dev,gym,ray]'
	touch $@

setup: $(BIN)/.installed

net: setup
	$(IRLSIM) net

# the suite's time budget (DEVELOPERS.md): the slowest tests printed, then tools/test_budget.py's report
# (TEST_WORKERS pytest processes, by test file: a file's tests and its fixtures stay in one process)
TEST_WORKERS ?= 2
test: setup
	@mkdir -p build
	$(BIN)/pytest -q -m "not slow" -n $(TEST_WORKERS) --dist loadfile --durations=15 \
		--junitxml=build/test-report.xml; rc=$$?; \
		$(BIN)/python tools/test_budget.py build/test-report.xml; exit $$rc

test-slow: setup
	$(BIN)/pytest -q -m slow

# make demo PRESET=tiny: the same chain on the smoke configs into data/tiny, runs/tiny (~30 s)
demo: setup
	$(IRLSIM) demo --data $(DATA) --runs $(RUNS) --seed $(SEED) --preset $(PRESET)

collect: setup
	$(IRLSIM) collect --config configs/collect/default.toml --out $(DATA)

# each stage has its own config and output folder: $(RUNS)/stage1/<model>/, $(RUNS)/stage2/<model>/
# (stage 2 reads its frozen PACNN / PACNN+S from $(RUNS)/stage1)
train: train-stage1 train-stage2

train-stage1: setup
	$(IRLSIM) train --stage 1 --config configs/train/stage1.toml --data $(DATA) --out $(RUNS)

train-stage2: setup
	$(IRLSIM) train --stage 2 --config configs/train/stage2.toml --data $(DATA) --out $(RUNS)

evaluate: setup
	$(IRLSIM) evaluate --data $(DATA) --runs $(RUNS) --out $(RUNS)/eval

drive: setup
	$(IRLSIM) drive --runs $(RUNS) --model expert,expert-theta,LIRL,PACNN+S,PTACNN+S --episodes 3 --laps 1 --seed 100 --config configs/collect/default.toml --out $(RUNS)/drive

# DAgger rounds on top of $(RUNS)'s PACNN+S (trained on $(DATA)): $(RUNS)/dagger/round_<r>/{data,runs}
dagger: setup
	$(IRLSIM) dagger --config configs/dagger/$(PRESET).toml --data $(DATA) --runs $(RUNS) --out $(RUNS)/dagger

bench: setup
	$(IRLSIM) bench --out bench

# how each cost grows with its size (planner, collection, disk, training, inference): bench/growth.{json,md,png}
# with the log-log slope of every curve (about 10 min on 2 cores; docs/results/growth.md "How each cost grows")
bench-growth: setup
	$(IRLSIM) bench --growth --out bench

# the transfer table (docs/results/transfer.md, "One reward, many roads"): five datasets, the zero-shot,
# leave-one-out (3 training seeds) and in-domain trainings, DAgger on the grid, Table I and the drives
transfer: setup
	nice -n 5 $(BIN)/python studies/transfer.py --out runs/transfer --seeds 0 1 2 --episodes 20 \
		--episodes-single 10 --dagger grid --threads 2 --workers 2

# the style study (docs/guide/demonstrators.md, "Does a learned reward drive in its demonstrator's style"):
# the expert, a cautious and an assertive SUMO driver on the oval and the motorway, 3 training seeds
styles: setup
	nice -n 5 $(BIN)/python studies/styles.py --out runs/styles --seeds 0 1 2 --episodes 20 --threads 2 --workers 2

# the paper-scale recipe, old and new side by side (docs/results/recipe.md, "Time to a driving reward"): one dataset,
# each recipe's stage 1 and DAgger rounds for 2 training seeds, timed, then their acceptance drives and Table I
recipe: setup
	nice -n 5 $(BIN)/python studies/recipe.py --out runs/recipe --recipes old new --seeds 0 1

# DAgger round sizes chosen by measurement (docs/results/recipe.md, "DAgger round sizes"): after `make recipe`, the
# new recipe's stage 1 with each schedule of rounds, driven on development seeds; the rule picks the cheapest
rounds: setup
	nice -n 5 $(BIN)/python studies/rounds.py --out runs/recipe --seeds 0 1 --schedules 6 6,10 6,20 --episodes 20

# "any SUMO network" at scale (docs/guide/sweeps.md, "Sweeps over many networks"): SWEEP_NETWORKS generated
# networks, 5 random car routes each (the first that loads driven by the expert), then every network of the
# eclipse-sumo wheel's tools/game/ with 20 routes each; resumable (rerun it after an interruption); estimated
# at 30-60 min at the default size on 2 cores. Small: make sweep SWEEP_NETWORKS=12
SWEEP          ?= runs/sweep
SWEEP_NETWORKS ?= 500
SWEEP_WORKERS  ?= 2
SUMO_GAME       = $$($(BIN)/python -c 'import sumo; print(sumo.SUMO_HOME)')/tools/game
sweep: setup
	$(IRLSIM) scenario generate --count $(SWEEP_NETWORKS) --seed $(SEED) --out $(SWEEP)/networks
	$(IRLSIM) scenario sweep $(SWEEP)/networks --routes 5 --drive 1 --seed $(SEED) --workers $(SWEEP_WORKERS) \
		--out $(SWEEP)/generated
	$(IRLSIM) scenario sweep "$(SUMO_GAME)" --routes 20 --drive 20 --seed $(SEED) --workers $(SWEEP_WORKERS) \
		--out $(SWEEP)/game

# ruff, mypy, the import contracts of pyproject.toml (layers point down, no cycles), and the size limits
lint: setup
	$(BIN)/ruff check irlsim pipelines tests studies tools examples
	$(BIN)/ruff format --check irlsim pipelines tests studies tools examples
	$(BIN)/mypy irlsim pipelines
	$(BIN)/lint-imports
	$(BIN)/python tools/check_sizes.py irlsim pipelines tests studies tools examples

$(BIN)/.docs-installed: pyproject.toml $(BIN)/.installed
	$(BIN)/pip install -q -e '.[docs]'
	touch $@

# HTML documentation (README, docs/**/*.md, the API reference from the docstrings) into build/docs; first
# tools/check_docs.py (no paragraph in two pages, no dead link or path), then Sphinx: warnings are errors
# (-W), and -E rebuilds every page so that none is skipped
docs: setup $(BIN)/.docs-installed
	$(BIN)/python tools/check_docs.py
	$(BIN)/sphinx-build -E -W --keep-going -q -b html docs build/docs
	@echo "docs: build/docs/index.html"

# redraw docs/img/import_graph.svg after changing imports between irlsim's packages (a test checks it)
import-graph: setup
	$(BIN)/python tools/import_graph.py

clean:
	rm -rf $(VENV) data runs bench build *.egg-info sumo_net/oval/oval.net.xml
