# The two commands a user needs: `make run` (the seed study) and `make test`.
# Both create the virtual environment and install everything on first use.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: run test fmus bench clean

run: $(STAMP)
	$(PY) -m mecanum_fmu fmus
	$(PY) -m mecanum_fmu run scenarios/circle.yaml

test: $(STAMP)
	$(PY) -m mecanum_fmu fmus
	$(PY) -m pytest

fmus: $(STAMP)
	$(PY) -m mecanum_fmu fmus

bench: $(STAMP)
	$(PY) -m mecanum_fmu fmus
	$(PY) bench/run_all.py

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --disable-pip-version-check -e '.[test]'
	touch $(STAMP)

clean:
	rm -rf fmus/*.fmu results build src/*.egg-info
