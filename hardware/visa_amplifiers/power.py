"""Driver of a remotely controlled power amplifier with a small generic SCPI command set,
implementing `hardware.interfaces.PowerAmplifier`.

Power amplifier command set (SCPI style):

    OUTP ON|OFF, OUTP?      output relay; the answer may be ON/OFF or 1/0
    GAIN <x>, GAIN?         gain as a fraction of full gain, 0..1 (linear, not dB)
    STAT:FAULT?             <code>,"<text>"; code 0 means no fault
    INT?                    interlock: 1 closed (safe to drive), 0 open
    *IDN?                   identity
"""

from __future__ import annotations

import math

from hardware.errors import AmplifierFaultError, InstrumentError
from hardware.visa_amplifiers.instrument import VisaInstrument
from hardware.visa_amplifiers.settings import (
    InRange,
    OneOf,
    Setting,
    parse_bool,
    parse_fault,
    parse_float,
)

# --------------------------------------------------------------------------------------------
# SCPI power amplifier
# --------------------------------------------------------------------------------------------

_PA_OUTPUT: Setting[bool] = Setting(
    "output",
    query="OUTP?",
    parse=parse_bool,
    set_command="OUTP {value}",
    validator=OneOf({True: "ON", False: "OFF"}),
)
_PA_GAIN: Setting[float] = Setting(
    "gain",
    query="GAIN?",
    parse=parse_float,
    set_command="GAIN {value}",
    validator=InRange(0.0, 1.0, unit="(fraction of full gain)"),
)
_PA_FAULT: Setting[str | None] = Setting("fault status", query="STAT:FAULT?", parse=parse_fault)
_PA_INTERLOCK: Setting[bool] = Setting("interlock", query="INT?", parse=parse_bool)


class ScpiPowerAmplifier(VisaInstrument):
    """A remotely controlled power amplifier with a generic SCPI command set.

    Gain is linear, 0..1 of full gain. `set_output_enabled(True)` refuses (AmplifierFaultError)
    while the interlock is open or a fault is reported; both directions read the output state
    back and raise if it did not change. `set_output_enabled(False)` needs no earlier call and
    may be called on any error path; it raises if it cannot confirm the output is off.
    """

    kind = "power amplifier"

    def set_output_enabled(self, enabled: bool) -> None:
        on = bool(enabled)
        if on:
            if not self.interlock_closed():
                raise AmplifierFaultError(
                    f"{self.label}: interlock open, output not enabled; close the exciter's "
                    "interlock (cover, over-travel switch) and try again"
                )
            fault = self.fault()
            if fault is not None:
                raise AmplifierFaultError(
                    f"{self.label}: reports a fault, output not enabled: {fault}; "
                    "clear the fault on the amplifier and try again"
                )
        self._set(_PA_OUTPUT, on)
        state = self._get(_PA_OUTPUT)
        if state != on:
            raise AmplifierFaultError(
                f"{self.label}: output still {'ON' if state else 'OFF'} after switching it "
                f"{'ON' if on else 'OFF'}; "
                + ("switch the amplifier off by hand" if not on else "check the amplifier")
            )

    def set_gain(self, gain: float) -> None:
        wire = _PA_GAIN.wire_value(gain, self.label)
        self._set(_PA_GAIN, gain)
        got = self.gain()
        if not math.isclose(got, float(wire), rel_tol=1e-6, abs_tol=1e-9):
            raise InstrumentError(f"{self.label}: gain reads {got:g} after setting {wire}")

    def gain(self) -> float:
        return self._get(_PA_GAIN)

    def fault(self) -> str | None:
        return self._get(_PA_FAULT)

    def interlock_closed(self) -> bool:
        return self._get(_PA_INTERLOCK)
