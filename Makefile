# Two entry points for a fresh machine: `make run` (full rig run) and `make test` (the suite).
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: setup run test lint bench

$(STAMP): requirements.txt setup.py
	python3 -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -r requirements.txt
	$(PY) -m pip install -q --no-deps -e .
	touch $(STAMP)

setup: $(STAMP)

run: setup
	$(VENV)/bin/lubrig simulate --case 1 --duration 10 --out runs/case1

test: setup
	$(PY) -m pytest -q test

lint: setup
	$(VENV)/bin/ruff check lubrig_ros test bench

bench: setup
	$(PY) bench/run_all.py
