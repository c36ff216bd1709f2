"""One calibration run from a request: the code path shared by the CLI and the GUI."""

from __future__ import annotations

import math
import signal
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from app.procedure import Finished, Listener, PreflightError, Procedure, RunSettings
from app.procedure.modes import MODE_MULTISINE
from app.records.run_folder import RunFolder
from app.stand import config as stand_config
from app.stand.open import open_stand
from app.stand.response import ResponseStore
from dsp.estimators import DEFAULT_ESTIMATOR
from dsp.multisine import PRESETS, Plan, make_plan, preset_plan
from sim.models import DUT_CATALOGUE, plan_preset_for
from sim.stand import Fault


@dataclass(frozen=True)
class RunRequest:
    """What the operator asked for (units in the names)."""

    stand_file: Path | None = None
    dut: str = "piezo"
    dut_id: str | None = None
    preset: str | None = None
    frequencies_hz: tuple[float, ...] | None = None  # custom lines on the preset's fs/period
    level_ms2: float = 5.0
    periods: int = 8
    target_type_a: float | None = None
    max_acquisition_s: float | None = None
    estimator: str = DEFAULT_ESTIMATOR
    mode: str = MODE_MULTISINE
    tolerance_percent: float | None = None
    nominal_mv_per_ms2: float | None = None
    seed: int = 0
    paced: bool = False
    faults: tuple[Fault, ...] = ()
    out: Path = Path("runs")
    dut_mass_g: float | None = None  # None: the simulated DUT's catalogue mass, else unstated
    stored_response: bool = True  # start equalisation from the stand's stored response
    response_store: Path | None = None  # where stored responses live (None: user data dir)

    def mass_g(self, backend: str) -> float | None:
        """The DUT mass the run states (g): given, else the simulated catalogue DUT's."""
        if self.dut_mass_g is not None or backend != "sim":
            return self.dut_mass_g
        return DUT_CATALOGUE[self.dut].mass_g

    def store(self) -> ResponseStore | None:
        """The stored-response store the run reads and refreshes, or None (--fresh-response)."""
        if not self.stored_response:
            return None
        if self.response_store is not None:
            return ResponseStore(self.response_store)
        return ResponseStore.default()

    def plan(self) -> Plan:
        name = self.preset or plan_preset_for(self.dut)
        if self.frequencies_hz is None:
            return preset_plan(name, level_ms2=self.level_ms2)
        preset = PRESETS[name]
        return make_plan(
            self.frequencies_hz,
            preset.sample_rate_hz,
            preset.period_samples,
            self.level_ms2,
            preset.reference_frequency_hz,
        )

    def settings(self, backend: str) -> RunSettings:
        """How to run on a stand of `backend` ("sim" or "nidaqmx": it decides the DUT mass)."""
        return RunSettings(
            dut_mass_g=self.mass_g(backend),
            periods=self.periods,
            target_type_a=self.target_type_a,
            max_acquisition_s=self.max_acquisition_s,
            estimator=self.estimator,
            mode=self.mode,
            tolerance_percent=self.tolerance_percent,
            dut_nominal_mv_per_ms2=self.nominal_mv_per_ms2,
        )


def check_request(request: RunRequest) -> None:
    """Refuse (PreflightError, naming the field) what must never reach a stand: a DUT not in the
    simulated stand's catalogue, a nominal DUT sensitivity that is not a finite positive
    number, a level or period count out of range."""
    if request.dut not in DUT_CATALOGUE:
        raise PreflightError(
            f"dut: {request.dut!r} is not in the DUT catalogue ({', '.join(DUT_CATALOGUE)})"
        )
    nominal = request.nominal_mv_per_ms2
    if nominal is not None and not (math.isfinite(nominal) and nominal > 0):
        raise PreflightError(f"nominal sensitivity: must be > 0 mV/(m/s^2), got {nominal:g}")
    if not (math.isfinite(request.level_ms2) and request.level_ms2 > 0):
        raise PreflightError(f"level: must be > 0 m/s^2, got {request.level_ms2:g}")
    if request.periods < 2:
        raise PreflightError(f"periods: at least 2, got {request.periods}")
    mass = request.dut_mass_g
    if mass is not None and not (math.isfinite(mass) and 0 <= mass <= 100_000):
        raise PreflightError(f"DUT mass: must be between 0 and 100000 g, got {mass:g}")


def prepare(request: RunRequest, listener: Listener | None = None) -> tuple[Procedure, Any]:
    """Load the stand, build the plan and check it before anything moves (PreflightError,
    ConfigError, PlanError on refusal; nothing is created then). Returns the procedure and the
    stand (to close)."""
    check_request(request)
    config = stand_config.load(request.stand_file)
    stand = open_stand(
        config,
        dut=request.dut,
        seed=request.seed,
        paced=request.paced,
        faults=request.faults,
        dut_mass_g=request.dut_mass_g,
    )
    try:
        plan = request.plan()
        identity = {
            "dut": {
                "catalogue": request.dut if config.backend == "sim" else None,
                "id": request.dut_id,
                "nominal_sensitivity_mv_per_ms2": request.nominal_mv_per_ms2,
            },
            "level_ms2": request.level_ms2,
        }
        procedure = Procedure(
            stand,
            plan,
            request.settings(config.backend),
            None,
            listener,
            identity=identity,
            response_store=request.store(),
        )
        procedure.preflight()
    except BaseException:
        stand.close()
        raise
    return procedure, stand


def start(request: RunRequest, listener: Listener | None = None) -> tuple[Procedure, Any]:
    """Prepare a run and give it its folder: the procedure (to `run()` on any thread, to
    `abort()` or `emergency_stop()` from another) and the stand (to close afterwards)."""
    procedure, stand = prepare(request, listener)
    try:
        procedure.folder = RunFolder.create(request.out, request.dut_id or request.dut)
    except BaseException:
        stand.close()
        raise
    return procedure, stand


def execute(request: RunRequest, listener: Listener | None = None) -> Finished:
    """Run a calibration to its end (complete or aborted) in a new run folder.

    SIGTERM, SIGHUP (terminal closed) and a first Ctrl-C ask for a fade-out; a second Ctrl-C
    stops at once. The drive ends at 0 V in every case (the procedure's own `finally`).
    """
    procedure, stand = prepare(request, listener)
    try:
        procedure.folder = RunFolder.create(request.out, request.dut_id or request.dut)
        with _graceful_signals(procedure):
            return procedure.run()
    finally:
        stand.close()


class _graceful_signals:
    """Route SIGTERM, SIGHUP and SIGINT to `procedure.abort` while a run is going (main thread
    only)."""

    def __init__(self, procedure: Procedure):
        self.procedure = procedure
        self.previous: dict[int, Any] = {}

    def __enter__(self) -> None:
        if threading.current_thread() is not threading.main_thread():
            return
        interrupted = {"count": 0}

        def on_term(signum: int, frame: Any) -> None:
            name = "SIGHUP" if signum == getattr(signal, "SIGHUP", None) else "SIGTERM"
            self.procedure.abort(f"terminated ({name})")

        def on_int(signum: int, frame: Any) -> None:
            interrupted["count"] += 1
            if interrupted["count"] > 1:
                raise KeyboardInterrupt
            self.procedure.abort("interrupted (Ctrl-C)")

        handlers = [(signal.SIGTERM, on_term), (signal.SIGINT, on_int)]
        if hasattr(signal, "SIGHUP"):  # POSIX: the terminal was closed
            handlers.append((signal.SIGHUP, on_term))
        for signum, handler in handlers:
            self.previous[signum] = signal.signal(signum, handler)

    def __exit__(self, *exc: object) -> None:
        for signum, handler in self.previous.items():
            signal.signal(signum, handler)
