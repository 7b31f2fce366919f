# Two entry points: `make demo` (set up + run the end-to-end demo) and `make test`.
# Both create the virtual environment in .venv when it is missing.
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.driveid-installed

.PHONY: demo test bench examples lint clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/driveid demo

# all cores (pytest-xdist); `$(BIN)/python -m pytest` alone runs the suite serially
test: $(STAMP)
	$(BIN)/python -m pytest -n auto
	$(BIN)/ruff check src tests benchmarks examples

bench: $(STAMP)
	for f in benchmarks/bench_*.py; do $(BIN)/python $$f || exit 1; done

examples: $(STAMP)
	for f in examples/*.py; do MPLBACKEND=Agg $(BIN)/python $$f --out examples-output --force || exit 1; done

lint: $(STAMP)
	$(BIN)/ruff check src tests benchmarks examples

clean:
	rm -rf $(VENV) build src/*.egg-info .pytest_cache
