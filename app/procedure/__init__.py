"""The calibration procedure (SPEC.md section 5), UI-agnostic, as small phase objects.

    preflight.py       the one preflight (CLI, GUI and the run): peaks against limits, ranges
    stand_io.py        drive-limit gate, output queue, fades, power amplifier, checked periods
    background.py      drive at 0 V: noise and hum per line, their budget terms
    identification.py  gentle drive: the stand's response per line
    equalisation.py    closed loop on the table acceleration per line
    acquisition.py     multisine periods until the stopping rule says stop
    stepped.py         stepped-sine mode, one line at a time
    stopping.py        the stopping rule both modes share (periods, type A target, time bound)
    procedure.py       Procedure: the phases in order, every way out, the run record
    request.py         the run request: the DUT resolved into a DutSpec, the run identity
    run.py             a request run: the stand opened, the procedure, the run folder
    teds_write.py      a run's result written to the DUT's TEDS (`accelcal teds write`)
    settings.py, events.py, errors.py, context.py

It drives any `hardware.interfaces.Daq` (and amplifiers), emits typed events to a listener,
writes the run folder as it goes, imports nothing from a UI and prints nothing. The drive ends
at 0 V on every path out of `Procedure.run()`. Names are imported from their module on first
use, so `from app.procedure import PreflightError` stays light. (No exported name equals a
submodule's: importing the submodule would replace it on the package.)
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from app.procedure.errors import (
    Aborted,
    DriveLimitError,
    PreflightError,
    ProcedureError,
    RunNotRecordedError,
)

if TYPE_CHECKING:
    from app.procedure.events import (
        EqualisationStep,
        Event,
        Finished,
        InputRanges,
        Listener,
        MemberEstimate,
        PeriodBlock,
        PeriodEstimate,
        Progress,
        State,
        StateChanged,
        WarningRaised,
    )
    from app.procedure.preflight import OVERLOAD_FRACTION, PreflightReport, check_preflight
    from app.procedure.procedure import Procedure
    from app.procedure.settings import MODES, RunSettings
    from app.procedure.stand_io import limited_drive
    from app.procedure.stopping import Stop, StoppingRule

_LAZY = {
    "EqualisationStep": "events",
    "Event": "events",
    "Finished": "events",
    "InputRanges": "events",
    "Listener": "events",
    "MemberEstimate": "events",
    "PeriodBlock": "events",
    "PeriodEstimate": "events",
    "Progress": "events",
    "State": "events",
    "StateChanged": "events",
    "WarningRaised": "events",
    "OVERLOAD_FRACTION": "preflight",
    "PreflightReport": "preflight",
    "check_preflight": "preflight",
    "Procedure": "procedure",
    "MODES": "settings",
    "RunSettings": "settings",
    "limited_drive": "stand_io",
    "Stop": "stopping",
    "StoppingRule": "stopping",
}
_RENAMED = {"_extrapolated": ("stepped", "extrapolated"), "_combine": ("stepped", "combine")}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        module, attribute = _LAZY[name], name
    elif name in _RENAMED:
        module, attribute = _RENAMED[name]
    else:
        raise AttributeError(f"module 'app.procedure' has no attribute {name!r}")
    value = getattr(importlib.import_module(f"app.procedure.{module}"), attribute)
    globals()[name] = value
    return value


__all__ = [
    "MODES",
    "OVERLOAD_FRACTION",
    "Aborted",
    "DriveLimitError",
    "EqualisationStep",
    "Event",
    "Finished",
    "InputRanges",
    "Listener",
    "MemberEstimate",
    "PeriodBlock",
    "PeriodEstimate",
    "PreflightError",
    "PreflightReport",
    "Procedure",
    "ProcedureError",
    "Progress",
    "RunNotRecordedError",
    "RunSettings",
    "State",
    "StateChanged",
    "Stop",
    "StoppingRule",
    "WarningRaised",
    "check_preflight",
    "limited_drive",
]
