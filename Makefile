# accelcal: every target creates the virtual environment when it is missing.
PYTHON ?= python3.11
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
DEMO_DIR ?= demo-output

.PHONY: venv test test-fast demo gui bench lint clean

venv: $(STAMP)

$(STAMP): pyproject.toml
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	@touch $(STAMP)

test: $(STAMP)
	QT_QPA_PLATFORM=offscreen $(BIN)/python -m pytest -q

# dsp, units, CLI parsing: under a minute on 2 cores (no runs, subprocesses, GUI, databases or
# Monte Carlo: markers `integration` and `slow`, see tests/conftest.py)
test-fast: $(STAMP)
	QT_QPA_PLATFORM=offscreen $(BIN)/python -m pytest -q -m "not slow and not integration"

demo: $(STAMP)
	$(BIN)/accelcal plan --preset piezo
	$(BIN)/accelcal run --sim --dut piezo --dut-id SN-DEMO-0001 --level 5 --periods 8 --seed 1 \
	    --tolerance 5 --out $(DEMO_DIR)/runs
	$(BIN)/accelcal certificate $$(ls -d $(DEMO_DIR)/runs/*/ | tail -n 1) --customer "ACME Ltd" \
	    --authorised-by "J. Smith, head of laboratory" --temperature 23 \
	    --mounting "stud-mounted back-to-back on the reference, 2 N m"

gui: $(STAMP)
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
	QT_QPA_PLATFORM=offscreen $(BIN)/python bench/gui_responsiveness.py

lint: $(STAMP)
	$(BIN)/ruff check dsp hardware sim app tests bench
	$(BIN)/ruff format --check dsp hardware sim app tests bench

clean:
	rm -rf $(VENV) $(DEMO_DIR) .pytest_cache
