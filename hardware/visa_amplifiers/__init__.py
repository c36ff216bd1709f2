"""VISA drivers for the stand's amplifiers (spec section 14): settings.py (the declarative
`Setting`, answer parsers, VISA error translation), instrument.py (what both drivers share),
bk2525.py and power.py (one driver each, with its command set).

- `BK2525Amplifier`: the Brüel & Kjær 2525 measuring (conditioning) amplifier, implementing
  `hardware.interfaces.MeasuringAmplifier`, per its User Manual Vol. 2 (sections cited in the
  code beside each command; what the readable pages did not settle is marked MANUAL UNREAD).
- `ScpiPowerAmplifier`: a remotely controlled power amplifier with a small generic SCPI command
  set, implementing `hardware.interfaces.PowerAmplifier`.

Every instrument setting is declared once, as a `Setting`: a human-readable name, the
set-command template, the query command, a parser for the answer and a validator (a range or a
list of allowed values). A value the validator refuses raises `InstrumentError` naming the
setting and what is allowed, before anything is written to the instrument. VISA failures are
translated into the stand's error types: a timeout becomes `VisaTimeoutError`; a lost
connection, a resource that is not found or a closed/invalid session becomes `DeviceLostError`;
an answer that cannot be parsed becomes `InstrumentError` quoting the answer.

Termination is '\\n' both ways. A driver owns the resource it was given or opened: `close()`
closes it (once; further calls do nothing). A resource manager passed in, or created here, is
never closed by the driver, since pyvisa shares one manager between all resources of a library.
After a timeout the instrument's late answer may still be in its output queue; close and reopen
the driver before using it again.
"""

from __future__ import annotations

from hardware.visa_amplifiers.bk2525 import (
    BK2525_GAINS,
    BK2525_HIGH_PASS_HZ,
    BK2525_LOW_PASS_HZ,
    BK2525_MODES,
    BK2525_SENSITIVITY_RANGE,
    BK2525Amplifier,
)
from hardware.visa_amplifiers.power import ScpiPowerAmplifier
from hardware.visa_amplifiers.settings import (
    InRange,
    OneOf,
    Setting,
    VisaResourceLike,
    parse_bool,
    parse_fault,
    parse_filter_hz,
    parse_float,
    parse_text,
    translate_visa_error,
)

__all__ = [
    "BK2525_GAINS",
    "BK2525_HIGH_PASS_HZ",
    "BK2525_LOW_PASS_HZ",
    "BK2525_MODES",
    "BK2525_SENSITIVITY_RANGE",
    "BK2525Amplifier",
    "InRange",
    "OneOf",
    "ScpiPowerAmplifier",
    "Setting",
    "VisaResourceLike",
    "parse_bool",
    "parse_fault",
    "parse_filter_hz",
    "parse_float",
    "parse_text",
    "translate_visa_error",
]
