# gnssrx developer entry points.  `make demo` and `make test` are the two set-up commands.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python

.PHONY: venv demo test test-fast lint docs docs-serve bench figures figures-leo figures-vector figures-carrier figures-check figures-compare batch-full batch-outages validate clean

$(VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e '.[test]'
	touch $@

# byte-compile the package (a shell with PYTHONDONTWRITEBYTECODE set would otherwise compile ~55 modules
# from source on every start-up: ~0.1 s of each run); cheap when nothing changed
venv: $(VENV)/.installed
	@$(PY) -m compileall -q receiver > /dev/null

demo: venv
	$(PY) scripts/tools/demo.py

test: venv
	$(PY) -m pytest -q -n auto --dist loadfile --durations=15

# the fast lane (< 1 min): everything not marked slow
test-fast: venv
	$(PY) -m pytest -q -n auto --dist loadfile -m "not slow"

lint: venv
	$(VENV)/bin/ruff check .

# the documentation site (mkdocs.yml, docs/): mkdocs --strict fails on any warning (broken link, missing page,
# unresolved API reference); the HTML goes to site/
$(VENV)/.docs-installed: docs/requirements.txt | venv
	$(PY) -m pip install -q -r docs/requirements.txt
	touch $@

docs: $(VENV)/.docs-installed
	$(PY) scripts/tools/gen_config_docs.py --check
	NO_MKDOCS_2_WARNING=1 $(VENV)/bin/mkdocs build --strict

docs-serve: $(VENV)/.docs-installed
	NO_MKDOCS_2_WARNING=1 $(VENV)/bin/mkdocs serve

bench: venv
	$(PY) scripts/bench/bench_tracking.py
	$(PY) scripts/bench/bench_simulate.py

# Figure runs: FIGJOBS = runs / processes at a time (vector batch -j, carrier --jobs; the LEO Monte Carlo is one
# process); FIGDIR = tables and figures; FIGDATA = the vector batch cache (recordings, run files): a second run
# into another FIGDATA recomputes everything.  FIGVECTOR_ARGS / FIGCARRIER_ARGS / FIGLEO_ARGS: extra options.
FIGJOBS ?= 2
FIGDIR ?= figures
FIGDATA ?= out/vector

figures: figures-leo figures-vector figures-carrier
	$(PY) scripts/figures/figures_index.py $(FIGDIR)

figures-leo: venv
	$(PY) scripts/figures/figures_leo.py --out $(FIGDIR)/leo $(FIGLEO_ARGS)

figures-vector: venv
	$(PY) scripts/figures/figures_vector.py --out $(FIGDIR)/vector --data $(FIGDATA) -j $(FIGJOBS) $(FIGVECTOR_ARGS)

figures-carrier: venv
	$(PY) scripts/figures/figures_carrier.py --out $(FIGDIR)/carrier --jobs $(FIGJOBS) $(FIGCARRIER_ARGS)

# compare two figure directories (e.g. two FIGDIRs made with different FIGJOBS) within the stated intervals
figures-compare: venv
	$(PY) scripts/figures/figures_compare.py $(A) $(B)

# a cheap seeded subset of the three figure scripts against configs/figures_reference.json (a few minutes;
# not part of `make test`); FIGCHECK_ARGS='--set tracking.carrier.ekf.bn_hz=12' shows it failing
figures-check: venv
	$(PY) scripts/figures/figures_check.py -j $(FIGJOBS) $(FIGCHECK_ARGS)

# outside-simulator validation matrix (GPS-SDR-SIM recordings; configs/validate/matrix.yaml): cached under
# out/validate/, table printed and written to docs/validation.md.  VALJOBS recordings at a time; VALIDATE_ARGS
# e.g. --only static_2048 (no doc update).
VALJOBS ?= 2
validate: venv
	$(PY) -m receiver.cli validate -j $(VALJOBS) $(VALIDATE_ARGS)

batch-full: venv
	$(VENV)/bin/gnssrx batch configs/batch/full.yaml
	$(VENV)/bin/gnssrx compare out/batch/full/summary.h5 --by variant

batch-outages: venv
	$(VENV)/bin/gnssrx batch configs/batch/outages.yaml
	$(PY) scripts/tools/outage_table.py out/batch/outages/summary.h5 --out out/batch/outages/acceptance.md

clean:
	rm -rf out figures site .pytest_cache
