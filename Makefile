# Quickstart: `make run` (main job on the embedded default) and `make test`.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: run test lint bench results bench-results twin-tables clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --no-cache-dir --upgrade pip
	$(BIN)/python -m pip install --quiet --no-cache-dir -e ".[dev]" --config-settings editable_mode=compat
	touch $(STAMP)

run: $(STAMP)
	$(BIN)/bladetwin run

# One worker per core, whole files per worker (module fixtures build their campaign once): design §8.32.
test: $(STAMP)
	$(BIN)/python -m pytest -q -n auto --dist loadfile --no-loadscope-reorder

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
	$(BIN)/python benchmarks/response.py --json docs/results/bench_response.json
	$(MAKE) results

# docs/results/twin_effects.md (the model against the bundled tests, before and after calibration) and
# docs/results/twin_compare.md (every headline figure, ideal twin against realistic, same code): about 20 min.
IDEAL := out/twin-ideal
twin-tables: $(STAMP)
	test -f out/academic/summary.json || $(BIN)/bladetwin run
	$(BIN)/bladetwin run --no-calibrate --out out/academic-uncalibrated --quiet
	test -f $(IDEAL)/campaign/campaign.toml || $(BIN)/bladetwin lab simulate --realism ideal --seed 0 --blades 18 \
		--grid 7x31 --level default --known 3,7,10,14,17 --name academic-ideal --out $(IDEAL)/campaign
	$(BIN)/bladetwin run $(IDEAL)/campaign --out $(IDEAL)/run --quiet
	mkdir -p docs/results
	$(BIN)/python -m bladetwin.twin_table effects out/academic/summary.json \
		out/academic-uncalibrated/summary.json measurements/academic/truth/truth.json > docs/results/twin_effects.md
	$(BIN)/python -m bladetwin.twin_table compare ideal=$(IDEAL)/run/summary.json \
		realistic=out/academic/summary.json > docs/results/twin_compare.md

clean:
	rm -rf $(VENV) .pytest_cache out
