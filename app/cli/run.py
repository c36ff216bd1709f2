"""`accelcal run`: a calibration (simulated stand unless --stand), one or a sweep of levels.
The request is built by app.procedure.request.build_request, as the GUI builds it."""

from __future__ import annotations

import argparse
import json
import os
import sys
from typing import TYPE_CHECKING

from app import formatting as fmt
from app.cli.exits import EXIT_ABORTED, EXIT_OK, UsageError
from app.cli.options import (
    faults_option,
    levels_option,
    parse_percent,
    parse_seconds,
    writable_folder,
)
from app.cli.printers import TerminalProgress, print_results

if TYPE_CHECKING:
    from app.procedure.run import RunRequest


def cmd_run(args: argparse.Namespace) -> int:
    from app.procedure.run import DutChoice, build_request, execute
    from dsp.spectral import check_periods

    if args.sim and args.stand:
        raise UsageError("--sim and --stand: choose one")
    try:
        check_periods(args.estimator, args.periods)  # issue 13 point 5 (dsp.spectral)
    except ValueError as exc:
        raise UsageError(f"--{exc}") from None
    faults = faults_option(args.fault)
    levels = levels_option(args.levels) if args.levels else None
    target = parse_percent(args.target_ua, "--target-ua") if args.target_ua else None
    max_time = parse_seconds(args.max_time, "--max-time") if args.max_time else None
    writable_folder(args.out, "--out")
    use_records = bool(args.sensor or args.db or os.environ.get("ACCELCAL_DB"))
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
    )
    for note in notes:
        print(note, file=sys.stderr)
    progress = None if args.json else TerminalProgress()
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
        if finished.results is not None:
            print_results(finished.results, record.run_id or "")
        print(f"run folder: {args.out / str(record.run_id)}")
        print(
            f"status: {record.status}"
            + (f" ({record.abort_reason})" if record.abort_reason else "")
            + f"; excitation {record.excitation_time_s:.1f} s; output now "
            + (f"{record.final_output_v:g} V" if record.final_output_v is not None else "unknown")
        )
    return EXIT_OK if record.complete else EXIT_ABORTED


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
    elif "sensitivity_mv_per_ms2" in summary:
        done = summary["levels_ms2"][: len(summary["sensitivity_mv_per_ms2"])]
        rows = [
            [
                f"{f:g}",
                *(f"{row[k]:.4f}" for row in summary["sensitivity_mv_per_ms2"]),
                f"{summary['linearity_percent'][k]:.3f}",
            ]
            for k, f in enumerate(summary["frequencies_hz"])
        ]
        print("Sensitivity in mV/(m/s^2) against frequency and level (m/s^2 per line)")
        print(fmt.table(["Hz", *(f"{lv:g}" for lv in done), "linearity %"], rows))
        print(
            f"Linearity: {summary['reference_linearity_percent']:.3f} % at "
            f"{summary['reference_frequency_hz']:g} Hz, worst "
            f"{summary['worst_linearity_percent']:.3f} % at "
            f"{summary['worst_linearity_frequency_hz']:g} Hz"
        )
    if not args.json:
        print(f"sweep summary: {summary['path']}; runs: {', '.join(map(str, summary['run_ids']))}")
        if summary["abort_reason"]:
            print(f"status: aborted ({summary['abort_reason']})")
    return EXIT_OK if sweep.complete else EXIT_ABORTED
