# The two commands of README.md. Both create (or reuse) .venv and install what they need.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
# make reproduce DATA=synthetic (default: no download, minutes on a CPU, writes runs/synthetic)
# make reproduce DATA=real      (the benchmark archives under $$ANSEG_DATA; writes figures/ and results/)
# make reproduce CONFIG=paper   (every run from a named configuration of anseg.configs instead of the plan's)
# make reproduce ONLY="table2 fig4"  (only the notebooks whose names contain one of these)
# make reproduce SPLITS="0"     (the notebooks that take several splits run on these alone)
DATA ?= synthetic
CONFIG ?=
ONLY ?=
SPLITS ?=

.PHONY: reproduce test clean lock

# the exact releases of requirements.lock (hashes checked), then the package itself without resolving again
$(STAMP): pyproject.toml requirements.lock
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet --require-hashes -r requirements.lock
	$(BIN)/python -m pip install --quiet --no-deps -e .
	$(BIN)/python -m ipykernel install --prefix $(VENV) --name anseg --display-name "anseg (.venv)" > /dev/null
	touch $(STAMP)

reproduce: $(STAMP)
	$(BIN)/python -m anseg.study.reproduce --data $(DATA) $(if $(CONFIG),--config $(CONFIG)) $(if $(ONLY),--only $(ONLY)) $(if $(SPLITS),--splits $(SPLITS))

test: $(STAMP)
	$(BIN)/ruff check anseg tests benchmarks scripts
	$(BIN)/python -m pytest -q --durations=15

# maintainers: refresh requirements.lock from pyproject.toml's ranges (pip-tools; keeps the pins it can)
lock:
	$(PYTHON) -m venv .venv-lock
	.venv-lock/bin/python -m pip install --quiet pip-tools==7.7.0
	.venv-lock/bin/pip-compile --quiet --extra notebooks --extra dev --generate-hashes --strip-extras --allow-unsafe \
		--no-emit-index-url --no-emit-find-links -o requirements.lock pyproject.toml

clean:
	rm -rf $(VENV) .venv-lock runs
