"""Simulated VISA instruments: the amplifiers of `sim/amplifiers.yaml` through pyvisa-sim.

    rm = simulated_resource_manager()
    amp = BK2525Amplifier(SIM_MEASURING_AMPLIFIER, rm, channels=SIM_MEASURING_AMPLIFIER_CHANNELS)
    pa = ScpiPowerAmplifier(SIM_POWER_AMPLIFIER, rm)

pyvisa keeps one library object per definitions path, so every manager returned with
`fresh=False` (the default) talks to the same simulated instruments for as long as one of them
is alive: their settings persist between users. `fresh=True` gives instruments of their own,
in their default state (the definitions are loaded from a private copy of the file).
"""

from __future__ import annotations

import importlib.resources
import shutil
import tempfile
from pathlib import Path
from typing import Any

import pyvisa

__all__ = [
    "SIM_DEFINITIONS",
    "SIM_MEASURING_AMPLIFIER",
    "SIM_MEASURING_AMPLIFIER_CHANNELS",
    "SIM_POWER_AMPLIFIER",
    "simulated_resource_manager",
]

#: Name of the pyvisa-sim definitions file shipped in this package.
SIM_DEFINITIONS = "amplifiers.yaml"
#: The simulated B&K 2525-style measuring amplifier and its number of channels.
SIM_MEASURING_AMPLIFIER = "GPIB0::12::INSTR"
SIM_MEASURING_AMPLIFIER_CHANNELS = 2
#: The simulated SCPI power amplifier.
SIM_POWER_AMPLIFIER = "ASRL1::INSTR"


def simulated_resource_manager(*, fresh: bool = False) -> pyvisa.ResourceManager:
    """A pyvisa resource manager on the `@sim` backend serving `sim/amplifiers.yaml`."""
    definitions = importlib.resources.files("sim") / SIM_DEFINITIONS
    with importlib.resources.as_file(definitions) as path:
        if not fresh:
            return pyvisa.ResourceManager(f"{path}@sim")
        # pyvisa-sim parses the file when the library is created, so the copy can go at once.
        with tempfile.TemporaryDirectory(prefix="accelcal-visa-sim-") as tmp:
            copy = Path(tmp) / SIM_DEFINITIONS
            shutil.copyfile(path, copy)
            return pyvisa.ResourceManager(f"{copy}@sim")


class FailingResource:
    """A pyvisa resource that raises a genuine VISA error (`code`) while `failing()` is true."""

    def __init__(
        self,
        resource: Any,
        failing: Any,
        code: pyvisa.constants.StatusCode = pyvisa.constants.StatusCode.error_timeout,
    ):
        self._resource = resource
        self._failing = failing
        self._code = code

    def _check(self) -> None:
        if self._failing():
            raise pyvisa.errors.VisaIOError(self._code)

    def write(self, message: str) -> Any:
        self._check()
        return self._resource.write(message)

    def query(self, message: str) -> str:
        self._check()
        return self._resource.query(message)

    def read(self) -> str:
        self._check()
        return self._resource.read()

    def __getattr__(self, name: str) -> Any:
        return getattr(self._resource, name)

    def __setattr__(self, name: str, value: Any) -> None:
        if name.startswith("_"):
            object.__setattr__(self, name, value)
        else:
            setattr(self._resource, name, value)
