# make bench: create .venv, install, run the main job (Table 1, whole sequences, BENCH_RUNS runs per cell) -> results/bench/
# make test: create .venv if needed, lint, run every test (what CI runs)
# make check: lint and the tests not marked slow (the inner loop)
# make results: remake every stale committed result (cnnslam results make), reusing the runs under runs/ still current
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed-stamp
JOBS   ?= 2
BENCH_FRAMES ?= all
BENCH_RUNS ?= 1

.PHONY: bench test check venv lint clean results

$(STAMP): pyproject.toml constraints.txt
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --disable-pip-version-check --no-compile -c constraints.txt -e '.[dev]'
	# byte-compile on $(JOBS) cores (the installed packages' own test suites left out; status 1: a py3.12-only file)
	$(BIN)/python -m compileall -qq -j $(JOBS) -x '/tests/' $(VENV)/lib cnnslam eval sim_envs slamcommon || true
	# numba's kernels compiled once into its cache (cnnslam/tools/warmup.py)
	$(BIN)/python -m cnnslam.tools.warmup --jobs $(JOBS) || echo "numba warm-up skipped: the first runs compile the kernels"
	touch $(STAMP)

venv: $(STAMP)

lint: venv
	$(BIN)/ruff check .
	$(BIN)/lint-imports --no-cache  # the layering: pyproject.toml's [tool.importlinter] contracts

test: venv lint
	$(BIN)/python -m pytest -n $(JOBS) --dist loadfile -q

check: venv lint
	$(BIN)/python -m pytest -n $(JOBS) --dist loadfile -q -m "not slow"

bench: venv
	$(BIN)/cnnslam bench table1 --frames $(BENCH_FRAMES) --runs $(BENCH_RUNS) --jobs $(JOBS) --results results/bench

results: venv
	$(BIN)/cnnslam results make --jobs $(JOBS)

clean:
	rm -rf $(VENV) .pytest_cache .ruff_cache *.egg-info
