# The two set-up commands (see README): `make demo` and `make test`.
# Both create the virtual environment .venv and install thirdhand into it first.

PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test lint install clean docs

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	touch $(STAMP)

install: $(STAMP)

# Real part meshes for the execution stage when the shared data sits beside the repository
# (otherwise the parts are their bounding boxes); a THIRDHAND_MESH_PATH of your own wins.
demo: export THIRDHAND_MESH_PATH ?= $(wildcard ../shared/data/3rdhand/meshes)

## The main job: synthetic chair demonstration through every stage, outputs in out/chair.
demo: $(STAMP)
	$(BIN)/thirdhand demo -o out/chair

## The whole test suite, with lint and type checks.
# One BLAS thread per worker: small matrix products are far slower with more on 2 cores.
test: $(STAMP) lint docs
	OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 $(BIN)/python -m pytest -n 2 --dist loadfile

## The documentation site, into site/ (offline; warnings are errors).
docs: $(STAMP)
	NO_MKDOCS_2_WARNING=1 DISABLE_MKDOCS_2_WARNING=true $(BIN)/mkdocs build --strict -d site

lint: $(STAMP)
	$(BIN)/ruff check src tests research benchmarks conftest.py
	$(BIN)/ruff format --check src tests research benchmarks conftest.py
	$(BIN)/mypy
	$(BIN)/lint-imports

clean:
	rm -rf $(VENV) out
