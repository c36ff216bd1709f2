"""Opt-in real-hardware tests: `pytest tests/hardware --daq-device Dev1 --visa-resource ...`."""

from __future__ import annotations

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
