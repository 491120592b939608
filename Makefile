# The two commands a user needs: `make run` (the seed study) and `make test`.
# Both create the virtual environment and install everything on first use.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: run test fmus bench bench-long clean bytecode

run: $(STAMP) bytecode
	$(PY) -m mecanum_fmu fmus
	$(PY) -m mecanum_fmu run scenarios/circle.yaml

# the tests on every core (pytest-xdist), each process with a TMPDIR of its own (tests/conftest.py);
# the heavy tests start first and an idle worker takes queued tests from a busy one (worksteal),
# so no long test is left alone at the end; the 15 slowest are listed at the end
test: $(STAMP) bytecode
	$(PY) -m mecanum_fmu fmus
	$(PY) -m pytest -n auto --dist worksteal --durations=15

fmus: $(STAMP)
	$(PY) -m mecanum_fmu fmus

# src/'s bytecode, written even where PYTHONDONTWRITEBYTECODE is set (as on CI machines): else
# every process compiles the package from source again (0.1-0.2 s a start; the tests start
# hundreds); only changed files are compiled again, and a stale .pyc is never used
bytecode: $(STAMP)
	$(PY) -m compileall -q src

# make bench: the quick benchmarks, under 3 minutes (it prints its time and the budget);
# make bench-long: memory against run length, endurance, the whole sweep (tens of minutes)
bench: $(STAMP)
	$(PY) -m mecanum_fmu fmus
	$(PY) bench/run_all.py

bench-long: $(STAMP)
	$(PY) -m mecanum_fmu fmus
	$(PY) bench/run_all.py --long

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --disable-pip-version-check -e '.[test]'
	touch $(STAMP)

clean:
	rm -rf fmus/*.fmu fmus/fmi3 results build src/*.egg-info
