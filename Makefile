# stage-emu: `make run` serves the default rig, `make test` runs every test. Both set up .venv first.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
ARGS ?=

.PHONY: run test bench soak lint clean venv

venv: $(STAMP)

# Setup is quiet: one line, and pip's full output only if it fails (it stays in .venv/setup.log).
$(STAMP): pyproject.toml
	@echo "stage-emu: setting up .venv (first run, or pyproject.toml changed)..." >&2
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	@( $(BIN)/python -m pip install --disable-pip-version-check --upgrade pip \
	  && $(BIN)/python -m pip install --disable-pip-version-check -e '.[test]' ) > $(VENV)/setup.log 2>&1 \
	  || { cat $(VENV)/setup.log >&2; echo "stage-emu: setup failed (log above, also in $(VENV)/setup.log)" >&2; exit 1; }
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
