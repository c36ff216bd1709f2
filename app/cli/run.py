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
    from app.procedure.batch import MemberChoice
    from app.procedure.options import RunOptions
    from app.procedure.service import BatchOutcome, PreparedRun, RunService


def run_options(args: argparse.Namespace) -> RunOptions:
    """The run's options from `accelcal run`'s command line (the table
    app.procedure.options.RUN_OPTIONS made the parser)."""
    from app.procedure.options import RunOptions

    if args.sim and args.stand:
        raise UsageError("--sim and --stand: choose one")
    writable_folder(args.out, "--out")
    models = [entry for entry in args.dut or [] if isinstance(entry, str)]
    values = {**vars(args), "dut": models[-1] if models else "piezo"}
    try:
        return RunOptions.from_values(
            values,
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


def batch_members(args: argparse.Namespace) -> list[MemberChoice]:
    """The DUTs of a run of several (`--dut POSITION=SERIAL` repeated, `--dut-model
    POSITION=MODEL`); [] for a single-DUT run. UsageError naming the option: a position or
    serial twice, a --dut-model for a position no --dut names, options that name one DUT."""
    from app.cli.options import dut_name
    from app.procedure.batch import MemberChoice

    pairs = [entry for entry in args.dut or [] if isinstance(entry, tuple)]
    if not pairs:
        if args.dut_model:
            raise UsageError("--dut-model: give the DUTs with --dut POSITION=SERIAL")
        return []
    for flag, given in (
        ("--dut-id", args.dut_id),
        ("--sensor", args.sensor),
        ("--teds", args.teds),
        ("--levels", args.levels),
    ):
        if given:
            raise UsageError(f"{flag}: names one DUT; with --dut POSITION=SERIAL give each DUT's")
    positions = [p for p, _ in pairs]
    for position in positions:
        if positions.count(position) > 1:
            raise UsageError(f"--dut: position {position!r} given twice")
    serials = [s for _, s in pairs]
    for serial in serials:
        if serials.count(serial) > 1:
            raise UsageError(f"--dut: serial {serial!r} given twice")
    models: dict[str, str] = {}
    for text in args.dut_model:
        position, _, model = text.partition("=")
        if position not in positions:
            raise UsageError(f"--dut-model {text}: no --dut names position {position!r}")
        try:
            models[position] = dut_name(model)
        except argparse.ArgumentTypeError as exc:
            raise UsageError(f"--dut-model {text}: {exc}") from None
    return [MemberChoice(p, s, models.get(p)) for p, s in pairs]


def cmd_run(args: argparse.Namespace) -> int:
    """`accelcal run`: parse, call the run service, show."""
    from app.procedure.service import RunService

    options = run_options(args)
    members = batch_members(args)
    levels = levels_option(args.levels) if args.levels else None
    service = RunService(options.stand_file)
    prepared = service.prepare(options)
    for note in prepared.notes:
        print(note, file=sys.stderr)
    if args.orientation is not None:
        return run_orientation(service, prepared, members, args)
    if members:
        return run_batch(service, prepared, members, args)
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


def run_orientation(
    service: RunService,
    prepared: PreparedRun,
    members: list[MemberChoice],
    args: argparse.Namespace,
) -> int:
    """`accelcal run --dut T=SN --orientation x|y|z`: a triaxial DUT in one orientation (its
    three channels, app.procedure.triaxial), then which orientation to mount next."""
    from app.procedure.triaxial import next_message, run_triaxial

    if len(members) != 1:
        raise UsageError("--orientation: give the triaxial DUT once, --dut POSITION=SERIAL")
    if args.dut_model:
        raise UsageError("--dut-model: a triaxial DUT's simulated sensor is sim/triaxial.py's")
    progress = None if args.json else TerminalProgress(None)
    batch = run_triaxial(service, prepared, members[0], args.orientation, listener=progress)
    if progress is not None:
        progress.close()
    return _print_batch(batch, args, next_message(members[0].position, args.orientation))


def run_batch(
    service: RunService,
    prepared: PreparedRun,
    members: list[MemberChoice],
    args: argparse.Namespace,
) -> int:
    """`accelcal run --dut A=SN1 --dut B=SN2 ...`: several DUTs in one run; each member's
    results as a single run's, then the batch."""
    progress = None if args.json else TerminalProgress(None)
    batch = service.run_batch(prepared, members, listener=progress)
    if progress is not None:
        progress.close()
    return _print_batch(batch, args)


def _print_batch(batch: BatchOutcome, args: argparse.Namespace, note: str = "") -> int:
    """A batch's members as a single run's each (or JSON), then the batch, then `note`
    (stderr with --json); its exit status."""
    if args.json:
        print(
            json.dumps(
                {
                    "batch_id": batch.batch_id,
                    "members": [
                        {
                            "position": m.position,
                            "serial": m.serial,
                            **json.loads(o.record.to_json()),
                        }
                        for m, o in batch.outcomes
                    ],
                },
                indent=2,
            )
        )
        if note:
            print(note, file=sys.stderr)
        return int(batch.exit_status)
    for member, outcome in batch.outcomes:
        if outcome.index_note:
            print(outcome.index_note, file=sys.stderr)
        print(f"--- position {member.position}: DUT {member.serial}")
        print_run_end(outcome.record, outcome.results, args.out / str(outcome.record.run_id))
        if args.resonance and outcome.results is not None:
            from app.procedure.analysis import CROSS_CHANNEL_REASON

            if CROSS_CHANNEL_REASON in outcome.results.verdict_reasons:
                print("resonance: not searched on a cross channel (a transverse sensitivity)")
            else:
                print(resonance_text(outcome.results.resonance))
    print(f"batch {batch.batch_id}: {len(batch.outcomes)} DUTs in {batch.folder}")
    if note:
        print(note)
    return int(batch.exit_status)
