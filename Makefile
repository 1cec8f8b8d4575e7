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

.PHONY: demo test bench bench-peers clean

$(STAMP): pyproject.toml constraints.txt
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
	$(PY) -m pip install --quiet -c constraints.txt -e '.[test]'
	@touch $(STAMP)

demo: $(STAMP)
	$(PY) demos/two_material_tube.py --out out/two_material_tube

test: $(STAMP)
	$(PY) -m pytest -q -n 2

bench: $(STAMP)
	$(VENV)/bin/ale-xfem bench

# PyClaw (clawpack) side by side with ours on Sod's tube; clawpack builds from source with
# gfortran and meson >= 1.2.3 (installed into .venv, with ninja and meson-python).
bench-peers: $(STAMP)
	@command -v gfortran >/dev/null 2>&1 || { \
	  echo "error: PyClaw builds with gfortran, which is not installed."; \
	  echo "Install it ('apt install gfortran' on Debian/Ubuntu, 'brew install gcc' on macOS) and run 'make bench-peers' again."; \
	  exit 1; }
	@$(PY) -c 'import clawpack.pyclaw' 2>/dev/null || { \
	  echo "installing PyClaw into $(VENV) (a few minutes: it compiles its Fortran Riemann solvers)"; \
	  $(PY) -m pip install --quiet 'meson>=1.2.3' ninja meson-python && \
	  PATH="$(CURDIR)/$(VENV)/bin:$$PATH" $(PY) -m pip install --quiet --no-build-isolation clawpack; }
	$(VENV)/bin/ale-xfem bench --peers

clean:
	rm -rf out .pytest_cache
