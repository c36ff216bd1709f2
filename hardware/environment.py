"""Driver of the stand's environment sensor: the Fluke (Hart Scientific) 1620A "DewK"
thermo-hygrometer, read over its serial port (RS-232, VISA ASRL) or Ethernet with its SCPI-style
command set. Ambient temperature in deg C, relative humidity in %.

Command set as the driver uses it (1620A User's Guide, chapter 8 "Digital Communications
Interface"; sections in brackets):

    *IDN?                     identity: maker,model,serial,firmware                  [8.4.1]
    FORM:TDST:STAT 0          time and date stamp off: MEAS? answers values only     [8.4.2.15]
    MEAS? <chn>               most recent measurement of a channel: "<T>,<RH>"       [8.4.2.16]
                              (manual's example: "MEAS? 1" -> "25.576,29.30")
    UNIT:TEMP?                the temperature unit, C or F (MANUAL UNREAD: the exact
                              spelling of the unit query is assumed from the 1620A's
                              SCPI tree; an F answer is converted, anything else refused)

Each command is its own message, terminated by '\\n' both ways (the 1620A accepts CR or LF).
A reading outside the sensor's physical range (temperature -40..150 deg C, humidity 0..100 %)
is refused as an InstrumentError quoting the answer; VISA failures are translated as for the
amplifiers (hardware.visa_amplifiers.settings).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from hardware.errors import InstrumentError
from hardware.visa_amplifiers.instrument import VisaInstrument
from hardware.visa_amplifiers.settings import OneOf, Setting, one_word_of, parse_bool

TEMPERATURE_RANGE_C = (-40.0, 150.0)  # what a 1620A probe can report
HUMIDITY_RANGE_PERCENT = (0.0, 100.0)

_TIMESTAMP: Setting[bool] = Setting(
    "time and date stamp",
    query="FORM:TDST:STAT?",
    parse=parse_bool,
    set_command="FORM:TDST:STAT {value}",
    validator=OneOf({True: "1", False: "0"}),
)
_UNIT: Setting[str] = Setting("temperature unit", query="UNIT:TEMP?", parse=one_word_of(["C", "F"]))
CHANNELS = (1, 2)  # the 1620A's two sensor inputs


@dataclass(frozen=True)
class EnvironmentReading:
    """Ambient temperature (deg C) and relative humidity (%) as read, with the sensor's
    identity (its *IDN? answer)."""

    temperature_c: float
    humidity_percent: float
    identity: str


class Fluke1620A(VisaInstrument):
    """The Fluke 1620A "DewK" thermo-hygrometer: `read()` gives one channel's temperature
    (deg C) and relative humidity (%)."""

    kind = "thermo-hygrometer"

    def read(self, channel: int = 1) -> EnvironmentReading:
        """The channel's most recent temperature and humidity, the time stamp switched off
        first (so the answer is the two values), in deg C whatever the display unit."""
        if isinstance(channel, bool) or channel not in CHANNELS:
            raise InstrumentError(f"{self.label}: channel {channel!r} refused: allowed 1 or 2")
        command = f"MEAS? {channel}"
        identity = self._identity or self.identify()
        self._set(_TIMESTAMP, False)
        unit = self._get(_UNIT)
        answer = self._query(command)
        fields = [f.strip() for f in answer.split(",")]
        try:
            if len(fields) != 2:
                raise ValueError("not two values")
            temperature, humidity = float(fields[0]), float(fields[1])
        except ValueError:
            raise InstrumentError(
                f"{self.label}: answer to {command!r} is not '<temperature>,<humidity>': {answer!r}"
            ) from None
        if unit == "F":
            temperature = (temperature - 32.0) * 5.0 / 9.0
        low, high = TEMPERATURE_RANGE_C
        if not (math.isfinite(temperature) and low <= temperature <= high):
            raise InstrumentError(
                f"{self.label}: temperature {answer!r} outside {low:g}..{high:g} C"
            )
        low, high = HUMIDITY_RANGE_PERCENT
        if not (math.isfinite(humidity) and low <= humidity <= high):
            raise InstrumentError(f"{self.label}: humidity {answer!r} outside {low:g}..{high:g} %")
        return EnvironmentReading(temperature, humidity, identity)
