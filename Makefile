# stage-emu: `make run` serves the default rig, `make test` runs every test. Both set up .venv first.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
ARGS ?=

.PHONY: run test bench soak lint typecheck clean venv compile

venv: $(STAMP)

# Setup prints one line per step and a few of pip's own (scripts/setup_step.py); pip's full output
# stays in .venv/setup.log and is shown only if a step fails.
SETUP_LOG := $(VENV)/setup.log
STEP := $(BIN)/python scripts/setup_step.py $(SETUP_LOG)
PIP := $(BIN)/python -m pip install --disable-pip-version-check

# The checkout (its packages, and the scripts and tests whose daemons import them) is byte-compiled
# once (plain .pyc in __pycache__, checked by timestamp), so no process compiles it again: with
# PYTHONDONTWRITEBYTECODE (CI machines) every process would otherwise compile every module it
# imports (a daemon: 0.3 s here, 3 s on a loaded machine). Only changed files are recompiled, so
# `compile` runs before every run, test, bench and soak.
COMPILE := $(BIN)/python -m compileall -q --invalidation-mode timestamp emulator protocols configs scripts tests

$(STAMP): pyproject.toml
	@echo "stage-emu: setting up .venv (first run, or pyproject.toml changed): 5 steps, a few minutes on a fresh machine" >&2
	@if test -x $(BIN)/python; then echo "stage-emu: [1/5] keeping the existing .venv" >&2; \
	  else echo "stage-emu: [1/5] creating .venv" >&2 && $(PYTHON) -m venv $(VENV); fi
	@: > $(SETUP_LOG)
	@$(STEP) "[2/5] upgrading pip" $(PIP) --upgrade pip
	@$(STEP) "[3/5] installing stage-emu and its run-time dependencies" $(PIP) -e .
	@$(STEP) "[4/5] installing the test extra (pytest, hypothesis, ruff, mypy, microscope, matplotlib)" \
	  $(PIP) -e '.[test]'
	@$(STEP) "[5/5] byte-compiling stage-emu" $(COMPILE)
	@touch $(STAMP)

compile: $(STAMP)
	@$(COMPILE)

run: compile
	@$(BIN)/stage-emu serve $(ARGS)

# pytest rewrites the asserts of each test module (and of the packages whose plugin it loads:
# emulator, protocols, configs) and keeps the result in a .pyc of its own, but never writes one under
# PYTHONDONTWRITEBYTECODE: every pytest process of `make test` (the xdist workers, the smoke runs, the
# client suites) would rewrite every module it imports again (3.6 s of CPU each on this 2-core
# machine). Collecting once with writing allowed leaves them; pytest checks each against its source
# as it always does. Redone when a source changes; a collection error is the next run's to report.
REWRITTEN := $(VENV)/.tests-rewritten
$(REWRITTEN): $(STAMP) $(shell find tests emulator protocols configs -name "*.py")
	@env -u PYTHONDONTWRITEBYTECODE $(BIN)/python -m pytest -q --collect-only -p no:cacheprovider >/dev/null 2>&1 || true
	@touch $@

# the type checks and the collection above side by side: each keeps one CPU busy
test: compile
	$(BIN)/ruff check .
	$(BIN)/ruff format --check --quiet .
	@$(MAKE) --no-print-directory -j2 typecheck $(REWRITTEN)
	$(BIN)/python -m pytest -q -n auto --dist loadgroup $(ARGS)

# every performance target (issue "Speed") in one table, exit 1 on a missed one; ARGS="--quick"
# (10-15 s), "--json FILE", "--only roundtrip timing ..."
bench: compile
	$(BIN)/python scripts/bench.py $(ARGS)

# the torture suite: every attack at full length, a table of figures, exit 1 past a bound; EXAMPLES
# randomized hypothesis examples per model property (`make test` runs short fixed forms of each)
EXAMPLES ?= 10000
soak: compile
	$(BIN)/python scripts/torture.py --examples $(EXAMPLES) $(ARGS)

lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	@$(MAKE) --no-print-directory typecheck

typecheck: $(STAMP)
	$(BIN)/mypy
	$(BIN)/mypy --strict protocols

clean:
	rm -rf $(VENV) build dist *.egg-info .pytest_cache .ruff_cache .mypy_cache .hypothesis
	find . -name __pycache__ -type d -prune -exec rm -rf {} +
