# Quickstart: `make run` (main job on the embedded default) and `make test`.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: run test lint bench results bench-results clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e ".[dev]" --config-settings editable_mode=compat
	touch $(STAMP)

run: $(STAMP)
	$(BIN)/bladetwin run

# One worker per core, whole files per worker (module fixtures build their campaign once): design §8.32.
test: $(STAMP)
	$(BIN)/python -m pytest -q -n auto --dist loadfile

lint: $(STAMP)
	$(BIN)/ruff check .

bench: $(STAMP)
	$(BIN)/python benchmarks/fe_modes.py

# docs/results.md and the README's figures from the last run's summary.json and the benchmarks' JSON files.
results: $(STAMP)
	test -f out/academic/summary.json || $(BIN)/bladetwin run
	mkdir -p docs/results && cp out/academic/summary.json docs/results/summary.json
	$(BIN)/python -m bladetwin.results_doc docs/results --readme README.md

# The benchmarks behind docs/results.md's performance table (about 15 min on 2 cores), then `make results`.
bench-results: $(STAMP)
	mkdir -p docs/results
	$(BIN)/python benchmarks/run_cold.py --json docs/results/bench_run.json
	$(BIN)/python benchmarks/ema.py --json docs/results/bench_ema.json
	$(BIN)/python benchmarks/ema_families.py --json docs/results/bench_ema_families.json
	$(BIN)/python benchmarks/rom.py --json docs/results/bench_rom.json
	$(BIN)/python benchmarks/dataset.py --json docs/results/bench_dataset.json
	$(BIN)/python benchmarks/posterior.py --json docs/results/bench_posterior.json
	$(MAKE) results

clean:
	rm -rf $(VENV) .pytest_cache out
