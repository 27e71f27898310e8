# RCI/RCCL: the two set-up commands are `make demo` and `make test`; both build .venv first.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

DERIVE_SRC := $(wildcard derive/*.py derive/*/*.py models/*.toml models/urdf/*.urdf)
DERIVED    := reports/thesis-equations.md

.PHONY: all venv derive test demo bench clean

all: test

venv: $(STAMP)

$(STAMP): pyproject.toml $(wildcard setup.py)
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	touch $(STAMP)

# Regenerate every derived file (generated kinematics code, derivation reports).
derive: $(STAMP)
	$(PY) -m derive

# Derive only when a derivation input is newer than its outputs.
$(DERIVED): $(DERIVE_SRC) | $(STAMP)
	$(PY) -m derive

test: $(STAMP)
	$(PY) -m pytest -q

demo: $(STAMP) $(DERIVED)
	$(PY) -m derive.crosscheck --samples 2000
	$(PY) -m rccl.plots
	$(VENV)/bin/calib report
	$(PY) examples/zero_gravity.py --simula "-c --warm" --cycles 180

bench: $(STAMP)
	$(PY) bench/rci_loop.py
	$(PY) bench/rccl_cycle.py
	$(PY) bench/calib_fit.py
	$(PY) -m pip install --quiet --no-deps -e .   # rebuild the C kernels from the current generated C
	$(PY) -m bench.run

clean:
	rm -rf $(VENV) build *.egg-info
