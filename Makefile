# gnssrx developer entry points.  `make demo` and `make test` are the two set-up commands.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python

.PHONY: venv demo test bench figures figures-leo figures-vector figures-carrier figures-check batch-full batch-outages clean

$(VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e '.[test]'
	touch $@

venv: $(VENV)/.installed

demo: venv
	$(PY) scripts/demo.py

test: venv
	$(PY) -m pytest -q -n auto --dist loadfile

bench: venv
	$(PY) scripts/bench_tracking.py
	$(PY) scripts/bench_simulate.py

figures: figures-leo figures-vector figures-carrier
	$(PY) scripts/figures_index.py figures

figures-leo: venv
	$(PY) scripts/figures_leo.py --out figures/leo

figures-vector: venv
	$(PY) scripts/figures_vector.py --out figures/vector

figures-carrier: venv
	$(PY) scripts/figures_carrier.py --out figures/carrier

# a cheap seeded subset of the three figure scripts against configs/figures_reference.json (a few minutes;
# not part of `make test`); FIGCHECK_ARGS='--set tracking.carrier.ekf.bn_hz=12' shows it failing
figures-check: venv
	$(PY) scripts/figures_check.py $(FIGCHECK_ARGS)

batch-full: venv
	$(VENV)/bin/gnssrx batch configs/batch/full.yaml
	$(VENV)/bin/gnssrx compare out/batch/full/summary.h5 --by variant

batch-outages: venv
	$(VENV)/bin/gnssrx batch configs/batch/outages.yaml
	$(PY) scripts/outage_table.py out/batch/outages/summary.h5 --out out/batch/outages/acceptance.md

clean:
	rm -rf out figures .pytest_cache
