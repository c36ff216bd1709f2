"""What stops a run: the procedure's exceptions (the message says what and what to do)."""

from __future__ import annotations

from app.errors import Refusal
from hardware.errors import (
    AmplifierFaultError,
    DeviceLostError,
    HardwareError,
    HardwareTimeoutError,
    OverloadError,
)


class ProcedureError(RuntimeError):
    """The run cannot go on; the message says what and what to do."""


class PreflightError(ProcedureError, Refusal):
    """The plan or level asks for more than the stand may do: refused before anything moves."""


# The abort reason of a run a PreflightError stopped (before anything moved, or before a level
# was played): the CLI exits 2 for it, not the aborted-run code 3 (issue 25 point 7).
REFUSED_BEFORE = "refused before anything moved: "
# ... or refused after a check played a reduced drive (issue 33 point 6: the reason said
# "before anything moved" after a 0.875 V check burst played for 4.4 s): it says what played
REFUSED_AFTER = "refused before the level was played, after a check: "


def refused_after(peak_v: float, played_s: float) -> str:
    """The abort reason's head when a refusal came after `played_s` s of drive up to
    `peak_v` V peak (the check bursts, fades included; faded out to 0 V since)."""
    return (
        f"{REFUSED_AFTER}{peak_v:.3f} V drive peak played for {played_s:.1f} s, then faded "
        "out to 0 V; "
    )


def refused(abort_reason: str | None) -> bool:
    """Whether a run's abort reason is a refusal (REFUSED_BEFORE, REFUSED_AFTER), not a stop."""
    return bool(abort_reason) and str(abort_reason).startswith((REFUSED_BEFORE, REFUSED_AFTER))


class Aborted(ProcedureError):
    """The run was stopped on request (operator, SIGTERM)."""


class DriveLimitError(ProcedureError):
    """A period of drive would exceed the stand's drive limit: refused, never played."""


class RunNotRecordedError(RuntimeError):
    """The run ended (drive at 0 V) but its status and results could not be stored."""


def advice(exc: HardwareError) -> str:
    """What the operator should do about a hardware error."""
    if isinstance(exc, OverloadError):
        return "Lower the level or raise the channel's range, then run again"
    if isinstance(exc, AmplifierFaultError):
        return (
            "Check the power amplifier (interlock, temperature, over-travel), reset it, run again"
        )
    if isinstance(exc, DeviceLostError):
        return "Reconnect the device (cable, power), then run again; the data so far is kept"
    if isinstance(exc, HardwareTimeoutError):
        return "Check that the instrument is on, connected and configured; then run again"
    return "Check the hardware, then run again"
