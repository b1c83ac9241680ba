# Two entry points for a fresh clone: `make demo` and `make test`.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: demo test lint bench clean browser

# Quiet unless something fails: the installers' output goes to $(VENV)/install.log, which is
# printed only when the install fails. The project is installed by uv (from PyPI, into the
# venv by pip; it resolves and links the ~100 wheels in parallel), or by pip when uv cannot be
# had or fails. Measured on the 2-core machine, a fresh clone, caches warm: pip 38 s, uv 7-12 s
# (uv's own install included; 7 s with a cold uv cache on a fast link).
UV_PIP = $(VENV)/bin/uv pip install --python $(PY)
$(STAMP): pyproject.toml
	@echo "setting up $(VENV) (under a minute from the installers' caches; log: $(VENV)/install.log)"
	@$(PYTHON) -m venv $(VENV)
	@{ { $(PY) -m pip install 'uv>=0.5,<1' && $(UV_PIP) -e '.[test]'; } \
		|| { echo "uv failed: installing with pip"; $(PY) -m pip install --upgrade pip \
		     && $(PY) -m pip install -e '.[test]'; }; } \
		> $(VENV)/install.log 2>&1 || { cat $(VENV)/install.log; echo "make: installing into $(VENV) failed (log above)"; exit 1; }
	@touch $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/gyrocal demo

# The suite runs in JOBS worker processes (pytest-xdist), a module per worker at a time so that a
# module's fixtures are built once; the long end-to-end modules (marked slow) start first. Two
# workers a core: about half of the suite's wall time is waiting (real-time runs, subprocesses,
# sockets), so a second worker per core fills it. Measured on the 2-core machine, load ~4:
# -n 2 7 min 07 s, -n 3 6 min 05 s, -n 4 5 min 42 s. `make test JOBS=1` runs it serially.
JOBS ?= $(shell echo $$(( 2 * $$(nproc 2>/dev/null || echo 1) )))
# The package's own modules are compiled to bytecode first, as pip compiles an installed
# package (an editable install is not): every process the suite starts (four workers, the
# fork servers, each `python -m gyrocal` a test runs) imports them, and in an environment
# that sets PYTHONDONTWRITEBYTECODE none of them would ever write what it compiled
# (measured: importing a run's modules 1.9 -> 1.6 s CPU, collecting the suite 10.1 -> 8.5 s
# a worker). Up-to-date files are skipped, so this costs a fraction of a second once done.
# The same for the test modules' assertion-rewritten bytecode, which pytest caches beside them
# but, there, never writes: each worker would rewrite all ~190 modules again (measured:
# collecting the suite 8.5 -> 5.3 s CPU a worker; writing them all, 2.1 s CPU, in parallel).
# The rewrite is pytest's own, byte for byte (tests/support/rewritten_bytecode.py).
SOURCES := gyrocal models instruments record analysis metrology orchestrator reports app tests
test: $(STAMP) browser
	$(VENV)/bin/ruff check .
	@$(PY) -m compileall -q -j 0 $(SOURCES)
	@$(PY) tests/support/rewritten_bytecode.py tests
	$(PY) -m pytest -q -n $(JOBS) --dist loadscope --no-loadscope-reorder

# The live page's test drives a real headless Chromium (Debian's chromium + chromium-driver).
# Installed only when missing, so a machine that has them pays one `command -v`.
browser:
	@if ! command -v chromium >/dev/null 2>&1 || ! command -v chromedriver >/dev/null 2>&1; then \
		if [ "$$(id -u)" = 0 ]; then SUDO=; else SUDO=sudo; fi; \
		$$SUDO apt-get update && $$SUDO apt-get install -y chromium chromium-driver; \
	fi

bench: $(STAMP)
	$(PY) benchmarks/run_all.py

clean:
	rm -rf $(VENV) build *.egg-info
