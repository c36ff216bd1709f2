"""Opt-in real-hardware tests: `pytest tests/hardware --daq-device Dev1 --visa-resource ...`."""

from __future__ import annotations

from pathlib import Path

import pytest


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption("--daq-device", default=None, help="NI-DAQmx device for *_with_device tests")
    parser.addoption("--visa-resource", default=None, help="VISA resource of a measuring amplifier")


@pytest.fixture()
def daq_device(request: pytest.FixtureRequest) -> str:
    device = request.config.getoption("--daq-device")
    if device is None:
        pytest.skip("real-hardware test: give --daq-device to run it")
    return device


@pytest.fixture()
def visa_resource(request: pytest.FixtureRequest) -> str:
    resource = request.config.getoption("--visa-resource")
    if resource is None:
        pytest.skip("real-hardware test: give --visa-resource to run it")
    return resource


# The fast tier (`make test-fast`: dsp, units, CLI parsing) leaves out whatever runs a
# calibration, a subprocess, the GUI, a database or a Monte Carlo study. Whole files are marked
# here by path, tests of other files by the fixtures they use (a completed calibration run, the
# Qt window); single tests elsewhere carry @pytest.mark.integration / slow themselves.
INTEGRATION_PATHS = (
    "app/db/",  # SQLite and PostgreSQL records databases, migrations, concurrent writers
    "app/test_certificate.py",  # fixture runs, PDFs
    "app/test_honest_numbers.py",  # calibration runs and recordings end to end
    "app/test_procedure.py",  # procedure runs, SIGTERM on a subprocess
    "app/test_records.py",  # run folders of real runs
    "app/test_run_integrity.py",  # runs, concurrent subprocesses
    "app/test_safety.py",  # runs with faults, signals to subprocesses
    "app/test_simulate.py",  # simulated recordings end to end
    "app/test_startup.py",  # fresh interpreters
    "gui/",  # the Qt window, live runs, soak
    "hostile/test_processes.py",  # subprocesses
)

INTEGRATION_FIXTURES = frozenset({"complete_run", "qtbot"})


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Mark the tests of INTEGRATION_PATHS, and those using INTEGRATION_FIXTURES, `integration`."""
    root = Path(__file__).resolve().parent
    for item in items:
        relative = Path(str(item.path)).resolve().relative_to(root).as_posix()
        fixtures = set(getattr(item, "fixturenames", ()))
        if relative.startswith(INTEGRATION_PATHS) or fixtures & INTEGRATION_FIXTURES:
            item.add_marker(pytest.mark.integration)
