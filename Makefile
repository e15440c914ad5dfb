# Two commands on a fresh machine with Python 3.11 and make:  make demo  /  make test
# More: make bench (benchmarks → docs/performance.md), make docs (the manual, --strict, into out/site),
#       make picture (the README's image, docs/img/plan_along_path.png), make clean,
#       make fuzz (every parser's fuzz target for FUZZ_MINUTES each, corpus kept in fuzz/).
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
TSTAMP := $(VENV)/.installed-test
DSTAMP := $(VENV)/.installed-docs
SITE   := out/site
FUZZ_MINUTES ?= 10
FUZZ_JOBS ?= 1

.PHONY: demo test fuzz bench docs picture clean

$(PY):
	@test -n "$(PYTHON)" || { echo "need python3.11 (or python3 >= 3.11) on PATH"; exit 1; }
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip

$(STAMP): pyproject.toml | $(PY)
	$(PY) -m pip install --quiet -e .
	@touch $@

$(TSTAMP): pyproject.toml | $(PY)
	$(PY) -m pip install --quiet -e '.[test]'
	@touch $(STAMP) $@

$(DSTAMP): pyproject.toml | $(PY)
	$(PY) -m pip install --quiet -e '.[docs]'
	@touch $(STAMP) $@

demo: $(STAMP)
	$(VENV)/bin/cctmill demo -o out

test: $(TSTAMP)
	$(PY) -m pytest

# The fuzz targets of tests/fuzz_targets.py (each reader, the job and plan loaders, each wire
# parser) for FUZZ_MINUTES minutes each; the corpus and any failing inputs stay in fuzz/. Exits
# non-zero when an input broke a target's rule; the table is also in fuzz/last_run.md.
fuzz: $(TSTAMP)
	$(PY) tests/fuzz_run.py --minutes $(FUZZ_MINUTES) --jobs $(FUZZ_JOBS)

# Every benchmark; writes out/benchmarks.md, docs/performance.md and the table of docs/validation.md.
bench: $(STAMP)
	$(PY) -m pip install --quiet -e '.[bench]'
	$(PY) benchmarks/run_all.py

# The job file reference in docs/job.md is generated from the schema (committed), then the manual is
# built with every warning an error.
docs: $(DSTAMP)
	$(PY) docs/gen_job_reference.py
	$(PY) docs/check_readme_links.py
	NO_MKDOCS_2_WARNING=1 $(VENV)/bin/mkdocs build --strict --clean --site-dir $(SITE)
	@echo "manual: $(SITE)/index.html"

# The image of the README and the manual's front page: the demo plan along its path, downsized.
picture: $(STAMP)
	$(VENV)/bin/cctmill plan --demo -o out
	$(PY) docs/make_picture.py out/plan_along_path.png docs/img/plan_along_path.png

clean:
	rm -rf $(VENV) out
