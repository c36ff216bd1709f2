"""Device discovery: NI devices through a fake System, VISA instruments through pyvisa-sim,
and the `accelcal devices` report on this machine (no NI driver)."""

from __future__ import annotations

from types import SimpleNamespace

import nidaqmx.errors
import pytest

from hardware.discovery import describe, list_ni_devices, list_visa_resources
from hardware.errors import DaqNotFoundError, HardwareError
from sim.visa import SIM_MEASURING_AMPLIFIER, SIM_POWER_AMPLIFIER, simulated_resource_manager


def driver_installed() -> bool:
    try:
        nidaqmx.system.System.local().driver_version  # noqa: B018
    except nidaqmx.errors.DaqNotFoundError:
        return False
    return True


def chans(*names):
    return [SimpleNamespace(name=n) for n in names]


def fake_system():
    return SimpleNamespace(
        devices=[
            SimpleNamespace(
                name="Dev1",
                product_type="USB-4431",
                ai_physical_chans=chans("Dev1/ai0", "Dev1/ai1"),
                ao_physical_chans=chans("Dev1/ao0"),
            )
        ]
    )


def test_list_ni_devices_from_system():
    assert list_ni_devices(fake_system()) == [
        {
            "name": "Dev1",
            "product_type": "USB-4431",
            "ai": ["Dev1/ai0", "Dev1/ai1"],
            "ao": ["Dev1/ao0"],
        }
    ]


@pytest.mark.skipif(driver_installed(), reason="NI-DAQmx driver installed here")
def test_list_ni_devices_without_driver():
    with pytest.raises(DaqNotFoundError, match=r"^NI-DAQmx is not installed: "):
        list_ni_devices()


def test_list_visa_resources_with_pyvisa_sim():
    rm = simulated_resource_manager(fresh=True)
    found = {r["resource"]: r for r in list_visa_resources(rm)}
    # The 2525 has no *IDN? (its command set, manual vol. 2 Table 9.1, has Identify? instead):
    # after the command error, discovery asks Identify? and drops the answer's long header.
    assert found[SIM_MEASURING_AMPLIFIER]["idn"] == "Bruel&Kjaer,2525,SIM-2525-0001,pyvisa-sim 1.0"
    assert found[SIM_POWER_AMPLIFIER]["idn"] == (
        "Simulated,SCPI power amplifier,SIM-PA-0001,pyvisa-sim 1.0"
    )
    assert all(r["error"] is None for r in found.values())
    rm.list_resources()  # a manager passed in stays open


class SilentResourceManager:
    def list_resources(self):
        return ("GPIB0::5::INSTR", "ASRL9::INSTR")

    def open_resource(self, name, **kwargs):
        if name.startswith("ASRL"):
            raise OSError("port busy")
        assert kwargs["timeout"] <= 2000
        return SimpleNamespace(
            query=lambda q: (_ for _ in ()).throw(TimeoutError("VI_ERROR_TMO")),
            close=lambda: None,
        )


def test_list_visa_resources_reports_errors():
    found = list_visa_resources(SilentResourceManager())
    assert found == [
        {"resource": "GPIB0::5::INSTR", "idn": None, "error": "no answer to *IDN?: VI_ERROR_TMO"},
        {"resource": "ASRL9::INSTR", "idn": None, "error": "cannot open: port busy"},
    ]


def test_list_visa_resources_without_visa_library():
    # this machine has neither NI-VISA nor pyvisa-py; skip if one is installed
    try:
        import pyvisa

        pyvisa.ResourceManager().close()
    except ValueError:
        pass
    else:
        pytest.skip("a VISA library is installed here")
    with pytest.raises(HardwareError, match="no VISA library"):
        list_visa_resources()


@pytest.mark.skipif(driver_installed(), reason="NI-DAQmx driver installed here")
def test_describe_on_this_machine():
    text = describe()
    assert "NI-DAQmx is not installed: " in text
    assert "VISA instruments:" in text


def test_describe_lists_what_it_finds():
    text = describe(simulated_resource_manager(fresh=True), fake_system())
    assert "Dev1: USB-4431" in text
    assert "AI: Dev1/ai0, Dev1/ai1" in text
    # no *IDN? on the 2525 (manual vol. 2, Table 9.1): identified by Identify? instead
    assert f"{SIM_MEASURING_AMPLIFIER}: Bruel&Kjaer,2525,SIM-2525-0001" in text


def test_describe_explains_empty_results():
    empty_rm = SimpleNamespace(list_resources=lambda: (), close=lambda: None)
    text = describe(empty_rm, SimpleNamespace(devices=[]))
    assert "NI-DAQmx is installed but sees no device" in text
    assert "VISA instruments:\n  none found" in text
