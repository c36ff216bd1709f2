"""`accelcal analyze`: re-analyse a recording (HDF5 of this program, CSV or TDMS)."""

from __future__ import annotations

import argparse
import json
import sys

from app.cli.exits import EXIT_OK, UsageError
from app.cli.options import output_target, writable_folder
from app.cli.printers import csv_with_status, print_results
from app.cli.readers import load_recording, recorded_estimator, recorded_transverse
from app.files import FileExistsRefusal, write_new

NO_BUDGET_WARNING = (
    "no type B budget (--budget): U is stated from type A (noise) only, without the "
    "reference's calibration, gains, mounting or distortion; not a calibration uncertainty"
)


def cmd_analyze(args: argparse.Namespace) -> int:
    from app.procedure.analysis import analyze, status_warning

    if not 0 < args.coverage < 1:
        raise UsageError(f"--coverage: must be between 0 and 1, got {args.coverage:g}")
    if args.segments is not None and args.segments < 1:
        raise UsageError(f"--segments: must be >= 1, got {args.segments}")
    if args.csv is not None:  # refused before any work: onto an input, a run, an existing file
        output_target(args.csv, "--csv", (args.file, args.budget), args.overwrite)
        writable_folder(args.csv.parent, "--csv")
    if args.seed_rule:
        from app.records.warnings import SEED_RULE_WARNING

        print(f"accelcal analyze: warning: {SEED_RULE_WARNING}", file=sys.stderr)
    from app.cli.analyze_batch import (
        batch_recording,
        cmd_analyze_batch,
        cmd_analyze_channels,
        several_dut_recordings,
    )

    batch = batch_recording(args.file)
    if batch is not None:  # several DUTs in one run: per DUT channel
        return cmd_analyze_batch(args, batch)
    several = several_dut_recordings(args)  # a CSV or TDMS of several DUTs: likewise
    if several is not None:
        if args.csv is not None:
            raise UsageError("--csv: one recording's table; a several-DUT file has one per DUT")
        return cmd_analyze_channels(args, several)
    recording = load_recording(args)
    if not recording.budget.components:  # a CSV or TDMS without --budget (or an empty one)
        print(f"accelcal analyze: warning: {NO_BUDGET_WARNING}", file=sys.stderr)
    analysis = analyze(
        recording,
        estimator=recorded_estimator(args),
        segments=args.segments,
        probability=args.coverage,
        rule="seed" if args.seed_rule else "gum",
        tolerance_percent=args.tolerance,
        mcm_trials=args.mcm,
        transverse=recorded_transverse(args.file),  # a triaxial cross channel's run: as run
    )
    results = analysis.results
    status = analysis.status or "unknown"  # a CSV recording carries no status
    if args.csv:
        table = csv_with_status(results.to_csv(), status)
        try:
            write_new(args.csv, table, overwrite=args.overwrite)
        except FileExistsRefusal as exc:
            raise UsageError(f"--csv: {exc} (--overwrite replaces it)") from None
    if args.json:
        note = status_warning(analysis.status)
        if note:
            print(f"accelcal analyze: warning: {note}", file=sys.stderr)
        print(json.dumps({"status": status, **results.to_dict(), **_reanalysed(args)}, indent=2))
    else:
        print_results(results, recording.source, analysis.status)
        _print_mcm(results)
    return EXIT_OK


def _print_mcm(results) -> None:
    """The JCGM 101 comparison per line and quantity, when --mcm was given."""
    from dsp.mcm import McmLine

    for m in results.mcm:
        print(McmLine(**m).summary())


def _reanalysed(args: argparse.Namespace) -> dict:
    """The re-analysis settings applied to a stored HDF5 recording (empty for CSV)."""
    if args.file.suffix.lower() not in (".h5", ".hdf5") and not args.file.is_dir():
        return {}
    applied = {
        "reference_frequency_hz": args.reference_frequency,
        "settle_periods_dropped": args.settle_periods,
        "mains_frequency_hz": args.mains,
    }
    applied = {k: v for k, v in applied.items() if v is not None}
    return {"reanalysis": applied} if applied else {}
