"""One calibration run from a request (app.procedure.request): the code path shared by the CLI
and the GUI, from the stand opened to the run folder written."""

from __future__ import annotations

import dataclasses
import signal
import threading
from typing import Any

from app.procedure import Finished, Listener, Procedure
from app.procedure.request import (
    DutChoice,
    RequestError,
    RunIdentity,
    RunRequest,
    build_request,
    check_request,
)
from app.records.run_folder import RunFolder
from app.stand.config import StandConfig, StandPlan
from app.stand.open import open_stand
from app.stand.simulated import EXCITERS, exciter_stroke_m

__all__ = [
    "DutChoice",
    "RunIdentity",
    "RunRequest",
    "build_request",
    "check_request",
    "execute",
    "prepare",
    "start",
]


def prepare(request: RunRequest, listener: Listener | None = None) -> tuple[Procedure, Any]:
    """Load the stand, build the plan and check it before anything moves (PreflightError,
    ConfigError, PlanError on refusal; nothing is created then). Returns the procedure and the
    stand (to close)."""
    check_request(request)
    # the stand file, with the reference standard's table from the records when they hold it
    config = with_exciter(request.stand_config(), request.exciter)
    request = with_stand_plan(request, config.plan)
    plan = request.plan(  # a custom plan is clipped and checked by the stroke before it opens
        config.limits.displacement_peak_to_peak_m if request.custom_plan else None
    )
    stand = open_stand(
        config,
        dut=request.dut,
        seed=request.seed,
        paced=request.paced,
        faults=request.faults,
        dut_mass_g=request.dut_mass_g,
        exciter=request.exciter,
    )
    try:
        if request.reference is not None:  # the records' table, not the simulator's own
            stand.chain = config.reference_chain()
            stand.budget = request.budget(stand.budget)  # and its uncertainty
        procedure = Procedure(
            stand,
            plan,
            request.settings(config.backend),
            None,
            listener,
            identity=request.identity(config.backend),
            response_store=request.store(),
            tolerances=request.tolerances(config.backend, plan.reference_frequency_hz),
        )
        procedure.preflight()
    except BaseException:
        stand.close()
        raise
    return procedure, stand


def with_stand_plan(request: RunRequest, plan: StandPlan) -> RunRequest:
    """The request with the stand file's [plan] where the request states nothing (its own
    options win; the profile when the request keeps the default, acceleration)."""
    changes: dict[str, Any] = {}
    for name in ("frequencies_hz", "sample_rate_hz", "period_samples", "reference_frequency_hz"):
        if getattr(request, name) is None and getattr(plan, name) is not None:
            changes[name] = getattr(plan, name)
    if request.profile == "acceleration" and plan.profile is not None:
        changes["profile"] = plan.profile
    if request.corner_hz is None and plan.corner_hz is not None:
        changes["corner_hz"] = plan.corner_hz
    return dataclasses.replace(request, **changes) if changes else request


def with_exciter(config: StandConfig, exciter: str | None) -> StandConfig:
    """The stand configuration with the simulated exciter `exciter`'s stroke as its travel
    limit (RequestError: unknown, or not a simulated stand)."""
    if exciter is None:
        return config
    if config.backend != "sim":
        raise RequestError("--exciter: only the simulated stand has an exciter catalogue")
    if exciter not in EXCITERS:
        raise RequestError(f"--exciter: {exciter!r} is not one of {', '.join(EXCITERS)}")
    limits = dataclasses.replace(
        config.limits, displacement_peak_to_peak_m=exciter_stroke_m(exciter)
    )
    return dataclasses.replace(config, limits=limits)


def start(request: RunRequest, listener: Listener | None = None) -> tuple[Procedure, Any]:
    """Prepare a run and give it its folder: the procedure (to `run()` on any thread, to
    `abort()` or `emergency_stop()` from another) and the stand (to close afterwards)."""
    procedure, stand = prepare(request, listener)
    try:
        procedure.folder = RunFolder.create(request.out, request.dut_id or request.dut)
        procedure.folder.records_chain_head = request.records_chain_head
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
        procedure.folder.records_chain_head = request.records_chain_head
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
