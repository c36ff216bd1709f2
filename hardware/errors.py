"""Errors of the stand's hardware, each a distinct type so the procedure can say what to do."""

from __future__ import annotations


class InputRefused(ValueError):
    """Bad input to a driver or codec (a TEDS file, an instrument's configuration), refused
    before any device is touched; the application treats it as bad input (app.errors)."""


class HardwareError(Exception):
    """Any failure of the DAQ or an amplifier."""


class HardwareTimeoutError(HardwareError):
    """A device did not answer or deliver data in time."""


class DaqTimeoutError(HardwareTimeoutError):
    """The DAQ did not deliver a period of samples within the read timeout."""


class VisaTimeoutError(HardwareTimeoutError):
    """A VISA instrument did not answer a query within its timeout."""


class DeviceLostError(HardwareError):
    """A device disappeared (unplugged, powered off, driver reset)."""


class OverloadError(HardwareError):
    """A channel reached its range limit (DAQ input or amplifier overload)."""

    def __init__(self, message: str, channel: str = ""):
        super().__init__(message)
        self.channel = channel


class AmplifierFaultError(HardwareError):
    """An amplifier reports a fault or an open interlock (over-travel, over-temperature...)."""


class InstrumentError(HardwareError):
    """An instrument refused a setting or answered something that cannot be parsed."""


class DaqNotFoundError(HardwareError):
    """The DAQ driver or the named device is not installed/present."""


class DaqNotSupportedError(HardwareError):
    """The DAQ device cannot do what the configuration asks (rate, channel, coupling...)."""
