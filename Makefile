# stage-emu: `make run` serves the default rig, `make test` runs every test. Both set up .venv first.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
ARGS ?=

.PHONY: run test bench soak lint clean venv

venv: $(STAMP)

# Setup prints one line per step and a few of pip's own (scripts/setup_step.py); pip's full output
# stays in .venv/setup.log and is shown only if a step fails.
SETUP_LOG := $(VENV)/setup.log
STEP := $(BIN)/python scripts/setup_step.py $(SETUP_LOG)
PIP := $(BIN)/python -m pip install --disable-pip-version-check

$(STAMP): pyproject.toml
	@echo "stage-emu: setting up .venv (first run, or pyproject.toml changed): 4 steps, a few minutes on a fresh machine" >&2
	@if test -x $(BIN)/python; then echo "stage-emu: [1/4] keeping the existing .venv" >&2; \
	  else echo "stage-emu: [1/4] creating .venv" >&2 && $(PYTHON) -m venv $(VENV); fi
	@: > $(SETUP_LOG)
	@$(STEP) "[2/4] upgrading pip" $(PIP) --upgrade pip
	@$(STEP) "[3/4] installing stage-emu and its run-time dependencies" $(PIP) -e .
	@$(STEP) "[4/4] installing the test extra (pytest, hypothesis, ruff, mypy, microscope, matplotlib)" \
	  $(PIP) -e '.[test]'
	@touch $(STAMP)

run: $(STAMP)
	@$(BIN)/stage-emu serve $(ARGS)

test: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check --quiet .
	$(BIN)/mypy
	$(BIN)/mypy --strict protocols
	$(BIN)/python -m pytest -q $(ARGS)

# every performance target (issue "Speed") in one table, exit 1 on a missed one; ARGS="--quick"
# (10-15 s), "--json FILE", "--only roundtrip timing ..."
bench: $(STAMP)
	$(BIN)/python scripts/bench.py $(ARGS)

# the torture suite: every attack at full length, a table of figures, exit 1 past a bound; EXAMPLES
# randomized hypothesis examples per model property (`make test` runs short fixed forms of each)
EXAMPLES ?= 10000
soak: $(STAMP)
	$(BIN)/python scripts/torture.py --examples $(EXAMPLES) $(ARGS)

lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/mypy
	$(BIN)/mypy --strict protocols

clean:
	rm -rf $(VENV) build dist *.egg-info .pytest_cache .ruff_cache .mypy_cache .hypothesis
	find . -name __pycache__ -type d -prune -exec rm -rf {} +
