# One-command set-up: every target installs what it needs on a fresh machine.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
# Debian packages: VTK (pyvista) offscreen rendering, libusb for pyusb, gcc for the PDM kernel.
DEBS   := libgl1 libegl1 libxrender1 libxext6 libusb-1.0-0 gcc

.PHONY: demo test bench lint format clean system-deps python-check fullwave FORCE

# PYTHON given (`make PYTHON=python3.12 demo`, or in the environment) naming another
# interpreter than the one .venv was made from: .venv is made again (emptied first,
# after python-check has accepted the new one; a PYTHON not found fails that check).
# Compared: the interpreters' real paths (the venv's base interpreter).
VENV_REMAKE :=
ifneq ($(filter command line environment,$(origin PYTHON)),)
ifneq ($(wildcard $(BIN)/python),)
WANT_PY := $(shell $(PYTHON) -c 'import os, sys; print(os.path.realpath(sys.executable))' 2>/dev/null)
HAVE_PY := $(shell $(BIN)/python -c 'import os, sys; print(os.path.realpath(sys._base_executable))' 2>/dev/null)
ifneq ($(WANT_PY),$(HAVE_PY))
VENV_REMAKE := --clear
ifeq ($(MAKELEVEL)$(if $(WANT_PY),,missing),0)
$(info .venv was made from $(or $(HAVE_PY),an unknown Python); PYTHON=$(PYTHON) is $(WANT_PY): making .venv again)
endif
endif
endif
endif

$(STAMP): pyproject.toml setup.py hardware/_pdm_kernel.c Makefile $(if $(VENV_REMAKE),FORCE)
	@$(MAKE) --no-print-directory python-check
	@$(MAKE) --no-print-directory system-deps
	$(PYTHON) -m venv $(VENV_REMAKE) $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e ".[all,dev]"
	@touch $(STAMP)

# pyproject.toml's requires-python, checked before a venv is made with the wrong one
python-check:
	@command -v $(PYTHON) >/dev/null 2>&1 || { echo "no $(PYTHON) on PATH: acousim needs Python >= 3.11 (make PYTHON=/path/to/python3.11)"; exit 1; }
	@$(PYTHON) -c 'import sys; v = sys.version_info; sys.exit(0 if v >= (3, 11) else "acousim needs Python >= 3.11; $(PYTHON) is %d.%d (make PYTHON=python3.11 ...)" % v[:2])'

system-deps:
	@if ! command -v dpkg >/dev/null 2>&1; then \
	  echo "not a Debian system: install the equivalents of $(DEBS) yourself (docs/setup.md)"; exit 0; \
	fi; \
	missing=""; for p in $(DEBS); do dpkg -s $$p >/dev/null 2>&1 || missing="$$missing $$p"; done; \
	if [ -n "$$missing" ]; then \
	  if [ "$$(id -u)" = 0 ]; then apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $$missing; \
	  else echo "missing Debian packages:$$missing (run as root or install them)"; fi; \
	fi

demo: $(STAMP)  ## simulate the corridor drive and write its pictures to out/
	$(BIN)/acousim demo --out out

test: $(STAMP)  ## type-check the public API, then run the test suite
	$(BIN)/mypy
	OPENBLAS_NUM_THREADS=1 $(BIN)/python -m pytest -q -n 2 --dist worksteal tests

bench: $(STAMP)  ## run every benchmark and rewrite BENCHMARKS.md
	$(BIN)/python -m benchmarks

fullwave: $(STAMP)  ## install the full-wave reference's extra (bempp-cl, pyopencl, Debian's pocl)
	@$(MAKE) --no-print-directory system-deps DEBS="pocl-opencl-icd"
	$(BIN)/python -m pip install --quiet -e ".[fullwave]"

lint: $(STAMP)  ## ruff, and mypy on the public API (its files: pyproject.toml [tool.mypy])
	$(BIN)/ruff check processing acousim hardware tests benchmarks
	$(BIN)/ruff format --check processing acousim hardware tests benchmarks
	$(BIN)/mypy

format: $(STAMP)
	$(BIN)/ruff format processing acousim hardware tests benchmarks
	$(BIN)/ruff check --fix processing acousim hardware tests benchmarks

clean:
	rm -rf $(VENV) out .pytest_cache .mypy_cache build hardware/*.so

FORCE:
