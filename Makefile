# Two commands for a fresh clone: `make demo` runs the main job, `make test` runs every test.
# Both create .venv and install the package with its dev extras on first use, then compile its
# kernels and the demo's solver once (a 1 s run), so that the first demo starts in seconds.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo demo-braking test test-fast bench results clean

$(STAMP): pyproject.toml constraints.txt
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -c constraints.txt -e ".[dev]"
	@echo "compiling the numba kernels and the lane change's C solver once (about 30 s)"
	$(BIN)/aac-sumo run lane_change --set scenario.duration=1 --out $(VENV)/warm-up > /dev/null
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/aac-sumo run lane_change --out out/

demo-braking: $(STAMP)
	$(BIN)/aac-sumo table braking --out out/table_braking

test: $(STAMP)
	$(BIN)/python -m pytest -q -n 2

test-fast: $(STAMP)
	$(BIN)/python -m pytest -q -n 2 -m "not slow"

bench: $(STAMP)
	$(BIN)/aac-sumo bench mpc --out out/bench

# Every published table into docs/results/ (hours on 2 cores; `python -m aac_sumo.tables.results --list` shows the jobs).
results: $(STAMP)
	$(BIN)/python -m aac_sumo.tables.results

clean:
	rm -rf $(VENV) out .pytest_cache .hypothesis
