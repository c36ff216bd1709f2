"""Shared test set-up: isolated Qt settings; opt-in real-hardware options
(`pytest tests/hardware --daq-device Dev1 --visa-resource ...`)."""

from __future__ import annotations

import atexit
import os
import shutil
import tempfile

import pytest

# before anything creates a QSettings: the whole session's Qt settings live in a temporary
# folder, never in the user's ~/.config (tests also get one folder each, below)
_CONFIG_HOME = tempfile.mkdtemp(prefix="accelcal-tests-config-")
os.environ["XDG_CONFIG_HOME"] = _CONFIG_HOME
atexit.register(shutil.rmtree, _CONFIG_HOME, ignore_errors=True)


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


@pytest.fixture(autouse=True)
def _isolated_qt_settings(tmp_path_factory: pytest.TempPathFactory) -> None:
    """Each test gets its own QSettings store (no window geometry, DUT or stand file carried
    from one test to the next, nothing read from or written to the user's own settings)."""
    try:
        from PySide6.QtCore import QSettings
    except ImportError:  # tests without Qt
        return
    folder = tmp_path_factory.mktemp("qsettings")
    for fmt in (QSettings.Format.NativeFormat, QSettings.Format.IniFormat):
        QSettings.setPath(fmt, QSettings.Scope.UserScope, str(folder))
