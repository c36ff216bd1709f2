# accelcal: every target creates the virtual environment when it is missing.
PYTHON ?= python3.11
VENV := .venv
# Python caches compiled modules (and pytest its rewritten tests) in __pycache__ folders; a shell
# that sets PYTHONDONTWRITEBYTECODE would make every test process and every `accelcal` the tests
# start compile the program again (about 10 s of each test worker's start)
unexport PYTHONDONTWRITEBYTECODE
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
DEMO_DIR ?= demo-output

.PHONY: venv test test-fast demo gui bench lint typecheck clean xvfb lock browser validate phases

venv: $(STAMP)

# requirements.lock pins the program's dependencies (and theirs) to what CI tested, and
# requirements-test.lock adds the test tools (pytest, ruff, mypy, ...) at versions resolved
# alongside them; `make lock` renews both. `make demo`, `make gui` and `make validate` install
# the program only (RUNTIME_STAMP); the test, lint, typecheck and bench targets add the tools.
RUNTIME_STAMP := $(VENV)/.installed-runtime

$(RUNTIME_STAMP): pyproject.toml requirements.lock
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -r requirements.lock
	$(BIN)/python -m pip install --quiet --no-deps -e .
	@touch $(RUNTIME_STAMP)

$(STAMP): $(RUNTIME_STAMP) requirements-test.lock
	$(BIN)/python -m pip install --quiet -r requirements-test.lock
	$(BIN)/python -m pip install --quiet --no-deps -e '.[test]'
	@touch $(STAMP)

# the program's dependencies resolved alone (requirements.lock), then the test extra installed
# under those pins: requirements-test.lock lists what it adds (and includes requirements.lock)
lock:
	rm -rf .lock-venv && $(PYTHON) -m venv .lock-venv
	.lock-venv/bin/python -m pip install --quiet --upgrade pip
	.lock-venv/bin/python -m pip install --quiet -e .
	{ echo "# The program's dependencies, pinned: what CI tested. \`make\` installs from here;"; \
	  echo "# \`make lock\` renews it (from pyproject.toml, in a fresh virtual environment)."; \
	  .lock-venv/bin/python -m pip freeze --exclude-editable | grep -v '^accelcal'; \
	} > requirements.lock
	.lock-venv/bin/python -m pip install --quiet -c requirements.lock -e '.[test]'
	{ echo "# The test tools (pyproject's test extra), pinned, over the program's own pins."; \
	  echo "# \`make lock\` renews it with requirements.lock."; \
	  echo "-r requirements.lock"; \
	  .lock-venv/bin/python -m pip freeze --exclude-editable | grep -v '^accelcal' \
	      | grep -vxF -f requirements.lock; \
	} > requirements-test.lock
	rm -rf .lock-venv

# a real X server for the GUI soak test, the X libraries Qt's xcb plugin loads, and pdftoppm
# (the certificate page-rendering test); installed
# (Debian, as root) only when missing
XVFB_PACKAGES := xvfb libxcb-icccm4 libxcb-keysyms1 libxcb-cursor0 libxcb-image0 \
	libxcb-render-util0 libxcb-randr0 libxcb-shape0 libxcb-xkb1 libxkbcommon-x11-0 libegl1 \
	poppler-utils

xvfb:
	@command -v dpkg >/dev/null || { echo "xvfb: not a Debian system; install Xvfb yourself"; exit 0; }; \
	missing=$$(for p in $(XVFB_PACKAGES); do dpkg -s $$p >/dev/null 2>&1 || echo $$p; done); \
	if [ -n "$$missing" ]; then \
	    echo "installing $$missing"; \
	    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $$missing; \
	fi

# Debian's Chromium and its chromedriver for the web view's browser test (tests/web, Selenium);
# installed (as root) only when missing
BROWSER_PACKAGES := chromium chromium-driver

browser:
	@command -v dpkg >/dev/null || { echo "browser: not a Debian system; install Chromium and chromedriver yourself"; exit 0; }; \
	missing=$$(for p in $(BROWSER_PACKAGES); do dpkg -s $$p >/dev/null 2>&1 || echo $$p; done); \
	if [ -n "$$missing" ]; then \
	    echo "installing $$missing"; \
	    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $$missing; \
	fi

# pytest-xdist: TEST_WORKERS processes share the tests (`make test TEST_WORKERS=0` runs them in
# this one process). Three on the 2-core machines for `make test`: its paced runs, fade-outs and
# subprocesses leave a core idle while they wait (the idle-machine figures: docs/benchmarks.md);
# two for `make test-fast`, whose tests only compute. --dist load: tests are dealt out in
# collection order (those marked `long` first: tests/conftest.py). Not loadgroup: in
# pytest-xdist 3.8 a worker that crashes under loadgroup leaves the run waiting for ever at
# its end (pytest-xdist issues 1323 and 1378; CI hung so at 99 % after a worker's SIGSEGV),
# where load reports the crashed test as failed and goes on. A test that runs past
# faulthandler_timeout (pyproject.toml, 30 min) has every thread's stack printed and its worker
# ended.
TEST_WORKERS ?= 3
FAST_WORKERS ?= 2
PYTEST_PARALLEL := -n $(TEST_WORKERS) --dist load

test: $(STAMP) xvfb browser
	QT_QPA_PLATFORM=offscreen $(BIN)/python -m pytest -q $(PYTEST_PARALLEL)

# dsp, units, CLI parsing: about a minute on 2 cores, 45-65 s idle (no runs, subprocesses, GUI,
# databases or Monte Carlo: markers `integration` and `slow`, see tests/conftest.py)
test-fast: $(STAMP)
	QT_QPA_PLATFORM=offscreen $(BIN)/python -m pytest -q -n $(FAST_WORKERS) --dist load \
	    -m "not slow and not integration"

# self-contained: its records file and stored stand responses live in $(DEMO_DIR)/data, so it
# neither reads nor writes the user's data directory and its timing does not depend on earlier runs
demo: export ACCELCAL_DATA_DIR = $(abspath $(DEMO_DIR))/data
demo: $(RUNTIME_STAMP)
	rm -rf $(DEMO_DIR)/data
	$(BIN)/accelcal plan --preset piezo
	@echo "== first run of this stand: a gentle identification burst, then the level (lpm, one period)"
	$(BIN)/accelcal run --sim --dut piezo --dut-id SN-DEMO-0001 --level 5 --seed 1 \
	    --tolerance 5 --technician "A. Tech" --out $(DEMO_DIR)/runs
	@echo "== second run: warm, from the stand response the first one stored (checked at 20 % first)"
	$(BIN)/accelcal run --sim --dut piezo --dut-id SN-DEMO-0001 --level 5 --seed 1 \
	    --tolerance 5 --technician "A. Tech" --out $(DEMO_DIR)/runs
	$(BIN)/accelcal certificate $$(ls -dt $(DEMO_DIR)/runs/*/ | head -n 1) --customer "ACME Ltd" \
	    --customer-address "Hauptstraße 1, 38100 Braunschweig" \
	    --authorised-by "J. Smith" --authorised-function "head of laboratory" --temperature 23 \
	    --mounting "stud-mounted back-to-back on the reference, 2 N m"

# the ISO/IEC 17025 7.11.2 software validation report of this version (exit 1: a case failed)
validate: $(RUNTIME_STAMP)
	mkdir -p $(DEMO_DIR)
	$(BIN)/accelcal validate --out $(DEMO_DIR)/validation-$$(date -u +%Y%m%dT%H%M%SZ).pdf

gui: $(RUNTIME_STAMP)
	$(BIN)/accelcal gui --sim

bench: $(STAMP)
	$(BIN)/python bench/crest_factor.py
	$(BIN)/python bench/analysis_speed.py
	$(BIN)/python bench/sim_speed.py
	$(BIN)/python bench/startup.py
	$(BIN)/python bench/coverage.py 600 piezo
	$(BIN)/python bench/estimators.py
	$(BIN)/python bench/excitation_time.py
	$(BIN)/python bench/records.py
	$(BIN)/python bench/import.py
	$(BIN)/python bench/impact.py 10000
	QT_QPA_PLATFORM=offscreen $(BIN)/python bench/gui_responsiveness.py

# the preset plans' optimised phases shipped in app/data/phases (app.procedure.phase_store):
# regenerate after a change to dsp/crestfactor.py or to a preset
# (tests/app/procedure/test_phase_store.py fails until then)
phases: $(STAMP)
	$(BIN)/python -m app.procedure.phase_store --write

typecheck: $(STAMP)
	$(BIN)/mypy dsp hardware sim app --ignore-missing-imports

lint: $(STAMP)
	$(BIN)/ruff check dsp hardware sim app tests bench
	$(BIN)/ruff format --check dsp hardware sim app tests bench

clean:
	rm -rf $(VENV) $(DEMO_DIR) .pytest_cache
