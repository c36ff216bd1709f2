"""`accelcal run`: a calibration (simulated stand unless --stand), one or a sweep of levels.
It parses its options into RunOptions and calls the run service (app.procedure.service), as
the GUI does; the exit status is the outcome's (app.procedure.outcome.ExitStatus)."""

from __future__ import annotations

import argparse
import json
import sys
from typing import TYPE_CHECKING

from app.cli.exits import UsageError
from app.cli.options import faults_option, levels_option, sim_hum_option, writable_folder
from app.cli.printers import TerminalProgress, print_run_end, print_sweep
from app.formatting import resonance_text

if TYPE_CHECKING:
    from app.procedure.options import RunOptions
    from app.procedure.service import PreparedRun, RunService


def run_options(args: argparse.Namespace) -> RunOptions:
    """The run's options from `accelcal run`'s command line (the table
    app.procedure.options.RUN_OPTIONS made the parser)."""
    from app.procedure.options import RunOptions

    if args.sim and args.stand:
        raise UsageError("--sim and --stand: choose one")
    writable_folder(args.out, "--out")
    try:
        return RunOptions.from_values(
            vars(args),
            stand_file=args.stand,
            sensor=args.sensor,
            db=args.db,
            teds=args.teds,
            stored_response=not args.fresh_response,
            paced=args.paced,
            faults=faults_option(args.fault),
            sim_hum=sim_hum_option(args.sim_hum),
            exact_mains_bins=args.exact_mains_bins,
            out=args.out,
            fail_exit=args.fail_exit,
            resonance=args.resonance,
        )
    except ValueError as exc:
        raise UsageError(str(exc)) from None


def cmd_run(args: argparse.Namespace) -> int:
    """`accelcal run`: parse, call the run service, show."""
    from app.procedure.service import RunService

    options = run_options(args)
    levels = levels_option(args.levels) if args.levels else None
    service = RunService(options.stand_file)
    prepared = service.prepare(options)
    for note in prepared.notes:
        print(note, file=sys.stderr)
    progress = None if args.json else TerminalProgress(sorted(levels) if levels else None)
    if levels is not None:
        return run_levels(service, prepared, levels, args, progress)
    outcome = service.run(prepared, listener=progress)
    if progress is not None:
        progress.close()
    if outcome.index_note:
        print(outcome.index_note, file=sys.stderr)
    record = outcome.record
    if args.json:
        print(record.to_json())
    else:
        print_run_end(record, outcome.results, args.out / str(record.run_id))
    if args.resonance and outcome.results is not None:
        print(resonance_text(outcome.results.resonance))
    return int(outcome.exit_status)


def run_levels(
    service: RunService,
    prepared: PreparedRun,
    levels: list[float],
    args: argparse.Namespace,
    progress: TerminalProgress | None,
) -> int:
    """`accelcal run --levels ...`: one run per level and the sweep summary."""
    try:
        sweep, status = service.sweep(prepared, levels, progress)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    if progress is not None:
        progress.close()
    summary = sweep.summary
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        print_sweep(summary)
    return int(status)
