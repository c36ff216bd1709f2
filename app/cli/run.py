"""`accelcal run`: a calibration (simulated stand unless --stand), one or a sweep of levels.
The request is built by app.procedure.request.build_request, as the GUI builds it."""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from typing import TYPE_CHECKING

from app.cli.exits import EXIT_ABORTED, EXIT_BAD_INPUT, EXIT_OK, UsageError
from app.cli.options import (
    faults_option,
    levels_option,
    parse_frequencies,
    parse_percent,
    parse_seconds,
    writable_folder,
)
from app.cli.printers import TerminalProgress, print_run_end, print_sweep

if TYPE_CHECKING:
    from app.procedure.run import RunRequest
    from dsp.calibration import Results


def cmd_run(args: argparse.Namespace) -> int:
    from app.procedure.run import DutChoice, build_request, execute
    from dsp.spectral import check_periods

    if args.sim and args.stand:
        raise UsageError("--sim and --stand: choose one")
    if args.periods is None:  # lpm: one record of one period; the others: 8 periods
        args.periods = 1 if args.estimator == "lpm" else 8
    try:
        check_periods(args.estimator, args.periods)  # issue 13 point 5 (dsp.spectral)
    except ValueError as exc:
        raise UsageError(f"--{exc}") from None
    if args.estimator == "lpm" and args.mode != "multisine":
        raise UsageError("--estimator lpm: analyses a multisine record; use --mode multisine")
    frequencies = tuple(parse_frequencies(args.frequencies)) if args.frequencies else None
    if args.profile != "acceleration" and args.corner is None:
        raise UsageError(f"--profile {args.profile}: needs --corner (Hz)")
    faults = faults_option(args.fault)
    levels = levels_option(args.levels) if args.levels else None
    # --target-ua is in percent like every percent option (0.2 and 0.2% are 0.2 %); the
    # procedure takes the relative type A as a fraction: converted once, here
    target = parse_percent(args.target_ua, "--target-ua") / 100 if args.target_ua else None
    max_time = parse_seconds(args.max_time, "--max-time") if args.max_time else None
    writable_folder(args.out, "--out")
    from app.records.db.engine import records_url

    # the records in use: --db, $ACCELCAL_DB or the default file (the answer `certificate` uses)
    use_records = bool(args.sensor) or records_url(args.db) is not None
    head = None
    if use_records:
        from app.records.db.gate import records_quick_check

        head = records_quick_check(args.db)
    choice = DutChoice(
        stand_file=args.stand,
        dut=args.dut,
        dut_id=args.dut_id,
        sensor=args.sensor,
        db=args.db,
        records=use_records,
        teds=args.teds,
        seed=args.seed,
        nominal_mv_per_ms2=args.nominal_sensitivity,
        tolerance_percent=args.tolerance,
        level_ms2=args.level,
        preset=args.preset,
        dut_mass_g=args.dut_mass,
        reference_override=args.reference_override,
    )
    request, notes = build_request(
        choice,
        periods=args.periods,
        target_type_a=target,
        max_acquisition_s=max_time,
        estimator=args.estimator,
        mode=args.mode,
        paced=args.paced,
        faults=faults,
        out=args.out,
        stored_response=not args.fresh_response,
        frequencies_hz=frequencies,
        sample_rate_hz=args.sample_rate,
        period_samples=args.period,
        reference_frequency_hz=args.reference_frequency,
        profile=args.profile,
        corner_hz=args.corner,
        exciter=args.exciter,
        fade_in_s=args.fade_in,
        technician=args.technician,
    )
    request = dataclasses.replace(request, records_chain_head=head)
    for note in notes:
        print(note, file=sys.stderr)
    progress = None if args.json else TerminalProgress(sorted(levels) if levels else None)
    if levels is not None:
        return run_levels(request, levels, args, progress)
    finished = execute(request, listener=progress)
    if progress is not None:
        progress.close()
    record = finished.record
    if use_records and record.run_id:
        from app.records.db.runs import index_finished_run

        print(index_finished_run(args.out / str(record.run_id), args.db), file=sys.stderr)
    if args.json:
        print(record.to_json())
    else:
        print_run_end(record, finished.results, args.out / str(record.run_id))
    if args.resonance and finished.results is not None:
        print(resonance_text(finished.results))
    return EXIT_OK if record.complete else exit_of_aborted(record.abort_reason)


def exit_of_aborted(abort_reason: str | None) -> int:
    """2 for a run refused before anything moved or before a level was played (the
    predicted displacement of the drive about to be played), 3 for one stopped."""
    from app.procedure.errors import refused

    return EXIT_BAD_INPUT if refused(abort_reason) else EXIT_ABORTED


def run_levels(request: RunRequest, levels: list[float], args: argparse.Namespace, progress) -> int:
    """`accelcal run --levels ...`: one run per level and the sweep summary."""
    from app.procedure.sweep import run_sweep

    try:
        sweep = run_sweep(request, levels, progress)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    if progress is not None:
        progress.close()
    summary = sweep.summary
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        print_sweep(summary)
    return EXIT_OK if sweep.complete else EXIT_ABORTED


def resonance_text(results: Results) -> str:
    """The mounted resonance the run's response shows (dsp.resonance), one line."""
    import numpy as np

    from dsp.resonance import ResonanceError, find_resonance

    f = np.array([line.frequency_hz for line in results.lines])
    h = np.array(
        [
            line.sensitivity_mv_per_ms2 * np.exp(1j * np.radians(line.phase_deg))
            for line in results.lines
        ]
    )
    try:
        found = find_resonance(f, h)
    except ResonanceError as exc:
        return f"resonance: none found ({exc})"
    return (
        f"resonance: mounted resonance at {found.frequency_hz:.0f} Hz, Q {found.q:.1f}, "
        f"{found.peak_ratio:.2f} x the lowest line ({found.lines_used} lines fitted)"
    )
