# Two commands do everything on a fresh machine:
#   make study   # install (first time) and run the whole default study -> results/
#   make test    # install (first time, with dev tools) and run the tests
PY ?= python3.11
VENV ?= .venv
BIN := $(VENV)/bin
CORES ?= 2

.PHONY: study test real smoke report bench lint venv clean

$(BIN)/python:
	@command -v $(PY) >/dev/null 2>&1 || { echo "need $(PY) (Python 3.11)"; exit 1; }
	$(PY) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip

$(VENV)/.installed: pyproject.toml | $(BIN)/python
	$(BIN)/pip install --quiet -e '.[dev]'
	touch $@

venv: $(VENV)/.installed

study: venv
	$(BIN)/snakemake --cores $(CORES)

real: venv
	$(BIN)/snakemake --cores $(CORES) --configfile config/real.yaml

smoke: venv
	$(BIN)/snakemake --cores $(CORES) --configfile config/smoke.yaml

report: venv
	$(BIN)/snakemake --cores $(CORES) --report results/report.html

test: venv
	$(BIN)/python -m pytest -q

bench: venv
	$(BIN)/python benchmarks/run_all.py

lint: venv
	$(BIN)/snakemake --lint
	$(BIN)/snakefmt --check Snakefile workflow/
	$(BIN)/ruff check .

clean:
	rm -rf results .snakemake
