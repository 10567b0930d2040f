VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.xted-installed

.PHONY: demo test test-fast install clean bench-grid

$(PY):
	python3 -m venv $(VENV)
	$(PY) -m pip install --upgrade pip

$(STAMP): $(PY) pyproject.toml constraints.txt
	$(PY) -m pip install -c constraints.txt -e ".[test]"
	touch $(STAMP)

install: $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/xted demo

test: $(STAMP)
	$(VENV)/bin/ruff check src tests benchmarks examples
	$(PY) -m pytest

test-fast: $(STAMP)
	$(VENV)/bin/ruff check src tests benchmarks examples
	$(PY) -m pytest -m "not slow" -x -q

bench-grid: $(STAMP)
	mkdir -p runs
	setsid nohup $(PY) tools/bench_unattended.py > runs/bench-grid.log 2>&1 &
	@echo "the bench grid runs in the background: runs/bench-grid.log (kill it any time; rerun to resume)"

clean:
	rm -rf $(VENV) build src/*.egg-info
