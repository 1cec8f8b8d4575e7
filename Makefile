# Set-up is two commands: `make demo` and `make test`. Both create .venv on first use.
SHELL := /bin/bash
VENV  := .venv
PY    := $(VENV)/bin/python
STAMP := $(VENV)/.installed

# A Python >= 3.12 (3.12 preferred): an explicit PYTHON=..., then python3.12/python3.13/python3 on PATH,
# then pyenv's installed versions (the bare pyenv shims fail unless pyenv selects them).
find_python = $(shell \
  for c in $(PYTHON) python3.12 python3.13 python3 \
           $$(ls -d $${PYENV_ROOT:-$$HOME/.pyenv}/versions/3.1[2-9]*/bin/python3 2>/dev/null | sort -V); do \
    if command -v $$c >/dev/null 2>&1 && $$c -c 'import sys; sys.exit(sys.version_info < (3, 12))' 2>/dev/null; then \
      command -v $$c; break; fi; done)

.PHONY: demo test bench clean

$(STAMP): pyproject.toml
	@if [ ! -x $(PY) ]; then \
	  base="$(find_python)"; \
	  if [ -z "$$base" ]; then \
	    echo "error: ale_xfem needs Python >= 3.12 and none was found."; \
	    echo "Install one (e.g. 'pyenv install 3.12' or 'apt install python3.12 python3.12-venv'), or run 'make PYTHON=/path/to/python3.12 test'."; \
	    exit 1; fi; \
	  echo "creating $(VENV) with $$base"; \
	  "$$base" -m venv $(VENV) || exit 1; \
	fi
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	@touch $(STAMP)

demo: $(STAMP)
	$(PY) demos/two_material_tube.py --out out/two_material_tube

test: $(STAMP)
	$(PY) -m pytest -q

bench: $(STAMP)
	$(VENV)/bin/ale-xfem bench

clean:
	rm -rf out .pytest_cache
