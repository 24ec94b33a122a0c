# Two commands: `make demo` (the main job on embedded defaults) and `make test`.
# Both create .venv and install the project on first use.

PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV := .venv
BIN := $(VENV)/bin
INSTALLED := $(VENV)/.installed
# The motion capture: the demo and the study app read $MOTION_DATA (by default both
# Bandai-Namco folders, studyapp/server/settings.py), the tests ../shared/data (tests/conftest.py).

.PHONY: demo demo-models test bench tour docs docs-reference messages install clean

install: $(INSTALLED)

# torch is installed first, pinned, so that the CPU build on this machine's disk is
# used; the project only asks for a range that it satisfies (see README for CUDA).
$(INSTALLED): pyproject.toml
	@$(PYTHON) -m venv $(VENV) || { echo "Cannot create a virtual environment: install python3-venv (e.g. apt-get install python3.11-venv)"; exit 1; }
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/python -c "import torch" 2>/dev/null || $(BIN)/pip install --quiet "torch==2.13.0"
	$(BIN)/pip install --quiet -e '.[dev]'
	@touch $@

# The whole suite on SQLite (the embedded default, whatever DATABASE_URL says), then the
# database tests again on PostgreSQL: the server DATABASE_URL names, or a throwaway
# cluster (tests/postgres_pass.py; PostgreSQL is installed when missing).
# Both passes run the test modules on TEST_WORKERS processes (pytest-xdist; a module stays
# in one process, with its fixtures), one more than the cores (at most 8): the browser
# tests wait on clips playing in real time more than they compute, and the modules with
# a slow test are started first (tests/conftest.py), so the others fill those waits.
TEST_WORKERS ?= $(shell n=$$(nproc); echo $$(( n < 8 ? n + 1 : 8 )))
PYTEST_PARALLEL = -n $(TEST_WORKERS) --dist loadfile --no-loadscope-reorder
test: $(INSTALLED)
	scripts/ensure-redis.sh
	scripts/ensure-r.sh
	scripts/ensure-chromium.sh
	scripts/ensure-caddy.sh
	scripts/ensure-axe.sh
	DATABASE_URL= $(BIN)/python -m pytest $(PYTEST_PARALLEL)
	$(BIN)/python -m tests.postgres_pass $(PYTEST_PARALLEL)
	$(BIN)/python -m mkdocs build --strict --quiet

# The documentation site (mkdocs.yml, docs/) at http://127.0.0.1:8001; make test builds it strictly.
docs: $(INSTALLED)
	$(BIN)/python -m mkdocs serve --dev-addr 127.0.0.1:8001

# docs/reference/*.md written again from the code: the command lines' parsers, the environment
# variables declared in studyapp/server/env.py, and benchmarks/results/*.json.
docs-reference: $(INSTALLED)
	$(BIN)/python scripts/docs_reference.py

demo: $(INSTALLED)
	$(BIN)/python -m studyapp.demo

# The demo's RNN, VAE and BAD MoGlow trained again into models/, with their digests
# (models/SHA256SUMS); `make demo` uses the committed ones and trains nothing itself.
demo-models: $(INSTALLED)
	PYTHON=$(BIN)/python scripts/train-demo-models.sh

# The participant pages' catalogues (studyapp/locale/*/LC_MESSAGES/django.po) written again from the
# code, then compiled to the committed django.mo: translate what is new or changed in each django.po
# and run it again (tests/test_participant_language.py fails until both are current). Needs GNU gettext;
# a new language starts with `cd studyapp && ../.venv/bin/python ../manage.py makemessages -l xx`.
messages: $(INSTALLED)
	cd studyapp && ../$(BIN)/python ../manage.py makemessages --all --no-location --no-obsolete
	cd studyapp && ../$(BIN)/python ../manage.py compilemessages

# The screenshots of docs/running-a-study.md, taken again by the tests' browser.
tour: $(INSTALLED)
	scripts/ensure-chromium.sh
	$(BIN)/python -m pytest -q tests/tour.py

bench: $(INSTALLED)
	$(BIN)/python benchmarks/run_all.py

clean:
	rm -rf var .pytest_cache
