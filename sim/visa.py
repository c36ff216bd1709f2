"""Simulated VISA instruments: the amplifiers of `sim/amplifiers.yaml` through pyvisa-sim.

    rm = simulated_resource_manager()
    amp = BK2525Amplifier(SIM_MEASURING_AMPLIFIER, rm, channels=SIM_MEASURING_AMPLIFIER_CHANNELS)
    pa = ScpiPowerAmplifier(SIM_POWER_AMPLIFIER, rm)

pyvisa keeps one library object per definitions path, so every manager returned with
`fresh=False` (the default) talks to the same simulated instruments for as long as one of them
is alive: their settings persist between users. `fresh=True` gives instruments of their own,
in their default state.

The YAML file is parsed once per process (about 0.1 s; a simulated run opens two fresh
managers): every library builds its own instruments from a copy of that one parsed definition,
so no two managers share state unless they share the library.
"""

from __future__ import annotations

import copy
import importlib.resources
import itertools
import threading
from typing import Any

import pyvisa
import yaml  # type: ignore[import-untyped]
from pyvisa.rname import to_canonical_name
from pyvisa_sim import parser
from pyvisa_sim.devices import Devices
from pyvisa_sim.highlevel import SimVisaLibrary

__all__ = [
    "SIM_DEFINITIONS",
    "SIM_ENVIRONMENT_DEFINITIONS",
    "SIM_ENVIRONMENT_SENSOR",
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
#: The simulated environment sensor (a Fluke 1620A thermo-hygrometer) and its definitions.
SIM_ENVIRONMENT_DEFINITIONS = "environment.yaml"
SIM_ENVIRONMENT_SENSOR = "ASRL3::INSTR"


def simulated_resource_manager(
    *, fresh: bool = False, definitions_name: str = SIM_DEFINITIONS
) -> pyvisa.ResourceManager:
    """A pyvisa resource manager on the `@sim` backend serving `sim/amplifiers.yaml` (or the
    package's `definitions_name`, e.g. SIM_ENVIRONMENT_DEFINITIONS)."""
    definitions = importlib.resources.files("sim") / definitions_name
    with importlib.resources.as_file(definitions) as path:
        name = str(path)
        if fresh:  # a library path of its own: pyvisa keeps one library object per path
            name += f"{_FRESH_MARK}{next(_fresh_count)}"
        return pyvisa.ResourceManager(_SharedDefinitionsLibrary(name))


_FRESH_MARK = "#fresh-"
_fresh_count = itertools.count(1)
_parsed: dict[str, dict[str, Any]] = {}
_parsed_lock = threading.Lock()


def parsed_definitions(path: str) -> dict[str, Any]:
    """The parsed pyvisa-sim definitions of the file at `path`, parsed once per process (a
    copy each call: the instruments built from it are the caller's own)."""
    with _parsed_lock:
        data = _parsed.get(path)
        if data is None:
            data = _parsed[path] = parse_file(path)
    return copy.deepcopy(data)


def parse_file(path: str) -> dict[str, Any]:
    """pyvisa_sim.parser.parse_file, read by libyaml's C BaseLoader when PyYAML has it (the
    same dict: every scalar a string; tests/sim/test_visa_sim.py): pyvisa-sim's pure-Python
    BaseLoader takes about 0.1 s of every simulated run's start-up (issue 34)."""
    loader = getattr(yaml, "CBaseLoader", None)
    if loader is None:  # pragma: no cover - PyYAML built without libyaml
        return parser.parse_file(path)
    with open(path, encoding="utf-8") as stream:
        data = yaml.load(stream, Loader=loader)
    if not isinstance(data, dict) or "spec" not in data:
        raise ValueError(f"{path}: does not specify a pyvisa-sim spec version")
    if parser._ver_to_tuple(data["spec"]) > parser.SPEC_VERSION_TUPLE:
        raise ValueError(f"{path}: spec version {data['spec']} is newer than pyvisa-sim's")
    return data


class _CachedLoader(parser.Loader):
    """pyvisa-sim's loader taking the definitions from `parsed_definitions`."""

    def _load(self, filename: Any, bundled: bool, required_version: int) -> dict[str, Any]:
        if bundled:
            return super()._load(filename, bundled, required_version)
        data = parsed_definitions(str(filename))
        version = parser._ver_to_tuple(data["spec"])[0]
        if version != required_version:
            raise ValueError(f"{filename}: spec version {version}, need {required_version}")
        return data


class _SharedDefinitionsLibrary(SimVisaLibrary):
    """pyvisa-sim's library with its instruments built from the once-parsed definitions
    (pyvisa_sim.parser.get_devices, with `_CachedLoader`). Its library path is the file's,
    with `#fresh-<n>` appended for a fresh one."""

    def _init(self) -> None:
        self.sessions: dict[int, Any] = {}
        path = str(self.library_path).split(_FRESH_MARK)[0]
        loader = _CachedLoader(path, False)
        devices = Devices()
        for resource_name, resource in loader.data.get("resources", {}).items():
            device_name = resource["device"]
            definition = loader.get_device_dict(
                device_name,
                resource.get("filename", None),
                resource.get("bundled", False),
                parser.SPEC_VERSION_TUPLE[0],
            )
            devices.add_device(
                to_canonical_name(resource_name),
                parser.get_device(device_name, definition, loader, resource),
            )
        self.devices = devices


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
