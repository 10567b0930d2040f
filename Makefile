VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.xted-installed

.PHONY: demo test install clean

$(PY):
	python3 -m venv $(VENV)
	$(PY) -m pip install --upgrade pip

$(STAMP): $(PY) pyproject.toml
	$(PY) -m pip install -e ".[test]"
	touch $(STAMP)

install: $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/xted demo

test: $(STAMP)
	$(VENV)/bin/ruff check src tests benchmarks examples
	$(PY) -m pytest

clean:
	rm -rf $(VENV) build src/*.egg-info
