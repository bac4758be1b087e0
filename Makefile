# Two entry points (see README): `make demo` and `make test`. Both create .venv and
# install torch==2.13.0 (CPU build) before the project, so no CUDA build is pulled.
VENV ?= .venv
PY := $(VENV)/bin/python
DEMO_SOURCE ?= synthetic:room?frames=40
DEMO_OUT ?= runs/demo

.PHONY: setup demo test clean

setup: $(VENV)/.installed

$(VENV)/.installed: pyproject.toml
	python3 -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q torch==2.13.0
	$(PY) -m pip install -q -e ".[test]"
	$(PY) -m nicer_stream.model.grid_kernel
	$(PY) -m nicer_stream.model.softplus
	$(PY) -m nicer_stream.model.positional
	$(PY) -m nicer_stream.denormals
	touch $@

demo: setup
	$(VENV)/bin/nicer-stream run --source "$(DEMO_SOURCE)" --out $(DEMO_OUT) --sink rerun:$(DEMO_OUT)/recording.rrd

test: setup
	$(VENV)/bin/pytest

clean:
	rm -rf $(VENV) runs
