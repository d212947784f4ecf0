# The two commands a newcomer needs (see README.md):
#   make bench   create .venv, install, run the main job (the Table-1 suite at the bench length -> results/bench/)
#   make test    create .venv if needed, lint, run the tests (all of them: what CI runs)
# and the inner loop's lane:
#   make check   lint and the tests not marked slow (the agent-run gates, the speed gate, whole-suite runs)
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed-stamp
JOBS   ?= 2
# the bench length: the Table-1 suite on the first BENCH_FRAMES frames of each of its 9 sequences x 8 methods x 3 runs
# (one for the oracle, which takes no seed), JOBS runs at a time; the shortest length whose ranking is the whole
# sequences' (results/lengths.md). The committed Table 1 (results/table1.md) is whole sequences: cnnslam bench table1.
# Finished runs under runs/ are reused, and so are rendered frames (runs/.frames/).
BENCH_FRAMES ?= 200

.PHONY: bench test check venv lint clean

$(STAMP): pyproject.toml constraints.txt
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --disable-pip-version-check -c constraints.txt -e '.[dev]'
	touch $(STAMP)

venv: $(STAMP)

lint: venv
	$(BIN)/ruff check .

test: venv lint
	$(BIN)/python -m pytest -n $(JOBS) --dist loadfile -q

check: venv lint
	$(BIN)/python -m pytest -n $(JOBS) --dist loadfile -q -m "not slow"

bench: venv
	$(BIN)/cnnslam bench table1 --frames $(BENCH_FRAMES) --jobs $(JOBS) --results results/bench

clean:
	rm -rf $(VENV) .pytest_cache .ruff_cache *.egg-info
