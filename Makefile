# Two entry points for a fresh machine with only Python 3.11:
#   make reproduce   set up .venv from the lock file, then run `snakemake reproduce-all`
#   make test        set up .venv from the lock file, Chromium and the C and AVR compilers (apt-get), lint,
#                    run the tests (tests/test_docs_site.py builds the documentation site with
#                    warnings as errors; in CI, tests/test_slurm.py runs on a one-node SLURM)
#   make docs        build the documentation site offline into docs/_build/html
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: setup reproduce test lint browser ccompiler lock clean docs

$(STAMP): pyproject.toml requirements.lock
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --disable-pip-version-check -r requirements.lock
	$(BIN)/python -m pip install --quiet --disable-pip-version-check --no-deps --no-build-isolation -e .
	touch $(STAMP)

setup: $(STAMP)

reproduce: $(STAMP)
	$(BIN)/snakemake reproduce-all

lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/snakefmt --check Snakefile workflow/rules

# Debian's Chromium and its driver, for the browser test of the HTML report
# (tests/test_report_browser.py); installed with apt-get only when missing.
browser:
	@if [ ! -x /usr/bin/chromium ] || [ ! -x /usr/bin/chromedriver ]; then \
		sudo=""; [ "$$(id -u)" -eq 0 ] || sudo="sudo"; \
		$$sudo env DEBIAN_FRONTEND=noninteractive apt-get update -qq && \
		$$sudo env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium chromium-driver >/dev/null; \
	fi

# A C compiler, for the tests that compile the exported controller header
# (tests/test_export.py), and the AVR one, for the test that the session player fits an
# ATmega328P (tests/test_plan_player.py); installed with apt-get only when missing.
ccompiler:
	@if ! command -v cc >/dev/null || ! command -v avr-gcc >/dev/null; then \
		sudo=""; [ "$$(id -u)" -eq 0 ] || sudo="sudo"; \
		$$sudo env DEBIAN_FRONTEND=noninteractive apt-get update -qq && \
		$$sudo env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq gcc libc6-dev \
			gcc-avr avr-libc >/dev/null; \
	fi

# In CI (CI=true) or with SPA_TEST_SLURM=1, tests/test_slurm.py starts a one-node SLURM
# (.ci/slurm.sh up: Debian's Slurm 22.05 installed with apt-get when missing) and stops it; the
# trap stops it too if pytest itself was killed.
# Two worker processes (pytest-xdist), one per core; a file's tests stay on one worker.
test: lint browser ccompiler
	@trap '.ci/slurm.sh down >/dev/null 2>&1 || true' EXIT; $(BIN)/pytest -n 2 --dist loadfile

# The documentation site (Sphinx, numpydoc, MyST, myst-nb, pydata-sphinx-theme): getting
# started (its tutorial runs the pipeline on the bundled example), how-to guides, explanation
# and reference; warnings are errors, judged as the suite judges them (docs/_site.py): Sphinx's
# exit status and its warnings file, not what the executed pages' kernels print on stderr.
# The executed pages are cached under a digest of what they use (docs/_execute.py).
docs: $(STAMP)
	@mkdir -p docs/_build
	$(BIN)/sphinx-build -b html -W --keep-going -j auto -q -w docs/_build/warnings.txt docs docs/_build/html
	@test ! -s docs/_build/warnings.txt || { cat docs/_build/warnings.txt; exit 1; }
	@echo "docs/_build/html/index.html"

# Regenerate the lock file from pyproject.toml (needs network access to the registry).
lock:
	rm -rf .lockenv && $(PYTHON) -m venv .lockenv
	.lockenv/bin/python -m pip install --quiet -e '.[test,docs]' snakemake-executor-plugin-slurm snakemake-executor-plugin-cluster-generic
	.lockenv/bin/python -m pip freeze --exclude-editable | grep -v '^spa' > requirements.lock
	rm -rf .lockenv

clean:
	rm -rf results .snakemake docs/_build docs/api docs/reference/generated docs/reference/cli.md docs/jupyter_execute
