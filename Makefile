# One venv for everything; every target installs what it needs first.
SHELL := /bin/bash
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
export HF_HUB_OFFLINE ?= 1
export MPLBACKEND ?= Agg

.PHONY: install test test-all lint demo bench clean-venv

install: $(STAMP)

$(STAMP): pyproject.toml
	@if [ ! -x $(PY) ]; then \
	  interp=$$(tools/find-python.sh) || exit 1; \
	  echo "creating $(VENV) with $$interp"; \
	  "$$interp" -m venv $(VENV) || exit 1; \
	fi
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e ".[test,ray,viz]"
	@# torchcodec comes with lerobot but cannot load without a system FFmpeg; LeRobot then prints a long
	@# traceback on every dataset it opens before falling back to PyAV. Absent, it falls back quietly.
	@$(PY) -c "import torchcodec" 2>/dev/null || $(PY) -m pip uninstall --quiet -y torchcodec
	@touch $(STAMP)

# The fast tier (<= 5 min on 2 cores); test-all adds the tests marked slow (what CI runs).
test: lint
	$(PY) -m pytest -q -m "not slow" $(PYTEST_ARGS)

test-all: lint
	$(PY) -m pytest -q $(PYTEST_ARGS)

lint: install
	$(VENV)/bin/ruff check .
	$(VENV)/bin/ruff format --check .

demo: install
	$(VENV)/bin/gcs-push demo $(DEMO_ARGS)

bench: install
	$(PY) -m benchmarks.run $(BENCH_ARGS)

clean-venv:
	rm -rf $(VENV)
