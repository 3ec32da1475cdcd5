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

.PHONY: reproduce test clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e ".[notebooks,dev]"
	$(BIN)/python -m ipykernel install --prefix $(VENV) --name anseg --display-name "anseg (.venv)" > /dev/null
	touch $(STAMP)

reproduce: $(STAMP)
	$(BIN)/python -m anseg.study.reproduce --data $(DATA) $(if $(CONFIG),--config $(CONFIG)) $(if $(ONLY),--only $(ONLY)) $(if $(SPLITS),--splits $(SPLITS))

test: $(STAMP)
	$(BIN)/ruff check anseg tests benchmarks scripts
	$(BIN)/python -m pytest -q --durations=15

clean:
	rm -rf $(VENV) runs
