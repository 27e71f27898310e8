# RCI/RCCL: the two set-up commands are `make demo` and `make test`; both build .venv first.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

# The derivation's inputs (derive/ and the models package: its loader, the kinematics contract,
# the robot files); their hash is kept beside the generated code so that `make demo`
# re-derives exactly when an input's content changed (not its file time).
DERIVE_SRC   := $(sort $(wildcard derive/*.py models/*.py models/*.toml models/urdf/*.urdf))
DERIVE_STAMP := rccl/kinematics/derived-from.sha256

.PHONY: all venv derive derive-if-needed test test-deps demo bench docs clean

all: test

venv: $(STAMP)

$(STAMP): pyproject.toml $(wildcard setup.py)
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip 'setuptools>=77'   # builds the wheel in tests/test_packaging.py
	$(PY) -m pip install --quiet -e '.[test]'
	touch $(STAMP)

# Regenerate every derived file (generated kinematics code, derivation reports), then
# rebuild the C kernels from the new C so the runtime does not fall back to Python.
derive: $(STAMP)
	$(PY) -m derive
	cat $(DERIVE_SRC) | sha256sum | cut -d' ' -f1 > $(DERIVE_STAMP)
	$(PY) -m pip install --quiet --no-deps -e .

# Derive only when the inputs differ from those the committed code was derived from.
derive-if-needed: $(STAMP)
	@if [ "$$(cat $(DERIVE_SRC) | sha256sum | cut -d' ' -f1)" = "$$(cat $(DERIVE_STAMP) 2>/dev/null)" ]; \
	then echo "derive: generated code is up to date with derive/ and models/"; \
	else $(MAKE) derive; fi

# What the tests need beyond .venv: a Chromium for tests/test_viewer.py, installed with apt-get
# (Debian's chromium) when none is found and we are root or have passwordless sudo; otherwise
# .ci/chromium says what to install and `make test` stops there (the browser test is never skipped)
test: $(STAMP) test-deps
	$(PY) -m pytest -q

test-deps:
	@./.ci/chromium

# The API reference from the docstrings (pdoc): docs/api/index.html, one page per module; fails
# on a broken reference (docs/api.py says what it checks)
docs: $(STAMP)
	$(PY) docs/api.py --out docs/api

# The demo's results go to $(DEMO_OUT)/ (untracked): timings and thread interleavings differ
# from run to run, so the committed reports/ are rebuilt only by their own commands (each
# report names it) and `git status` stays clean after a demo.
DEMO_OUT := demo-out

demo: derive-if-needed
	mkdir -p $(DEMO_OUT)
	$(PY) -m derive.crosscheck --samples 2000 --out $(DEMO_OUT)/crosscheck.md
	$(PY) -m rccl.plots --out $(DEMO_OUT)
	$(VENV)/bin/calib report --out $(DEMO_OUT)/calibration.md
	$(PY) examples/zero_gravity.py --simula "-c --warm" --cycles 180
	$(PY) examples/adaptive_circle.py --plot --out $(DEMO_OUT)/adaptive-circle.png
	$(PY) examples/adaptive_press.py --plot --out $(DEMO_OUT)/adaptive-press.png
	@echo "demo: results in $(DEMO_OUT)/: $$(ls $(DEMO_OUT) | tr '\n' ' ')"

bench: $(STAMP)
	$(PY) bench/rci_loop.py
	$(PY) -m bench.faults
	$(PY) -m bench.zenoh_flags
	$(PY) bench/rccl_cycle.py
	$(PY) bench/rccl_adaptive.py
	$(PY) bench/calib_fit.py
	$(PY) -m bench.feedforward --robot puma260 --robot microbo --robot puma560 --robot stanford --no-rotor \
	    --report reports/feedforward.md --plot reports/feedforward.png
	$(PY) -m bench.collision
	$(PY) -m bench.identification --robot puma260 --out reports/identification.md
	$(PY) -m bench.identification --robot puma560 --out reports/identification-puma560.md
	$(PY) -m bench.identification --robot stanford --out reports/identification-stanford.md
	$(PY) -m pip install --quiet --no-deps -e .   # rebuild the C kernels from the current generated C
	$(PY) -m bench.run
	$(PY) -m bench.ik_redundant   # the Panda's closed-form IK with q7 free: reports/ik-redundant.md

clean:
	rm -rf $(VENV) build *.egg-info
