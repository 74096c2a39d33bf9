# gnssrx developer entry points.  `make demo` and `make test` are the two set-up commands.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
SHARED ?= ../shared/data

.PHONY: venv demo test bench figures figures-leo clean

$(VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e '.[test]'
	touch $@

venv: $(VENV)/.installed

demo: venv
	$(PY) scripts/demo.py

test: venv
	$(PY) -m pytest -q

bench: venv
	$(PY) scripts/bench_tracking.py

figures: figures-leo

figures-leo: venv
	$(PY) scripts/figures_leo.py --out figures/leo

clean:
	rm -rf out figures .pytest_cache
