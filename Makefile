# policylab: the two set-up commands are `make demo` and `make test`.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: demo test bench lint clean venv mutate docs docs-serve

venv: $(STAMP)

# pip byte-compiles what it installs one file at a time: half of the install's time. It
# installs without that, then compileall does the same work on every core, for policylab's
# own source too (an editable install, which pip does not compile). The modules must be
# compiled here: where PYTHONDONTWRITEBYTECODE is set, Python never caches what it
# compiles on import, and every process (each CLI call, test worker and Ray worker) would
# compile torch and policylab anew. As pip does, a file that does not compile on this
# Python (a test file written for a newer one) is skipped, quietly.
$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet --no-compile -e '.[deep,dev,docs,games,mujoco,sweep]'
	$(PY) -m compileall -qq -j 0 "$$($(PY) -c 'import sysconfig; print(sysconfig.get_path("purelib"))')" src || true
	touch $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/policylab tour

test: $(STAMP)
	$(PY) -m pytest -n 2 --dist loadfile

docs: $(STAMP)
	NO_MKDOCS_2_WARNING=1 $(VENV)/bin/mkdocs build --strict --site-dir site

docs-serve: $(STAMP)
	NO_MKDOCS_2_WARNING=1 $(VENV)/bin/mkdocs serve --strict

bench: $(STAMP)
	$(PY) -m pip install --quiet -e '.[deep,dev,games,mujoco,sweep,bench]'
	$(PY) benchmarks/run.py $(BENCH)

# Mutation testing of the equations (not part of `make test`; 45 min on 2 loaded cores).
mutate: $(STAMP)
	$(PY) tools/mutate.py --out MUTATION.md

lint: $(STAMP)
	$(VENV)/bin/ruff check src tests benchmarks tools docs/hooks
	$(VENV)/bin/ruff format --check src tests benchmarks tools docs/hooks
	$(VENV)/bin/mypy

clean:
	rm -rf $(VENV) build site *.egg-info src/*.egg-info .pytest_cache .mypy_cache .ruff_cache
