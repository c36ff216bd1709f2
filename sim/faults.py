"""The simulated stand's fault kinds: the one list (CLI `--fault`, sim.stand), importable light."""

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
