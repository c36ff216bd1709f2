"""The simulated stand's faults: the one list of kinds (CLI `--fault`, sim.stand) and `Fault`, a
kind at a simulated time in s; importable light (no numpy)."""

from __future__ import annotations

import math
from dataclasses import dataclass

FAULT_KINDS = (
    "daq-timeout",
    "device-lost",
    "visa-timeout",
    "amplifier-fault",
    "overload",
    "over-current",
    "interlock",
    "amplifier-lost",
)
#: Faults of the power amplifier: injected through its pyvisa-sim instrument when the stand
#: has one (`power_amplifier()`), else (`amplifier-fault` only) raised by the DAQ read.
POWER_AMPLIFIER_FAULT_KINDS = ("amplifier-fault", "over-current", "interlock", "amplifier-lost")


@dataclass(frozen=True)
class Fault:
    """A fault of kind FAULT_KINDS at a simulated time in s after start."""

    kind: str
    at_s: float

    def __post_init__(self) -> None:
        if self.kind not in FAULT_KINDS:
            raise ValueError(f"fault: unknown kind {self.kind!r}; one of {', '.join(FAULT_KINDS)}")
        if not (math.isfinite(self.at_s) and self.at_s >= 0):
            raise ValueError(f"fault: time must be >= 0 s, got {self.at_s!r}")

    @classmethod
    def parse(cls, text: str) -> Fault:
        """'device-lost@3.5' -> Fault('device-lost', 3.5)."""
        kind, _, at = text.partition("@")
        try:
            return cls(kind.strip(), float(at))
        except ValueError as exc:
            raise ValueError(f"--fault {text!r}: expected KIND@SECONDS ({exc})") from None
