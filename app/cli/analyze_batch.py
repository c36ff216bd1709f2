"""`accelcal analyze` of a batch (issue 36: several DUTs in one run): the all-channel
recording analysed per DUT channel, the pair (reference, dut.<position>), by the same
analysis as a single recording; each DUT with its own budget and the simulated truth (hence
the catalogue DUT's tolerances) of its member run, when the member's folder is beside the
batch; else the batch recording's budget, said so."""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path
from typing import Any

from app.cli.exits import EXIT_OK, UsageError
from app.cli.printers import print_results
from app.cli.readers import recorded_transverse


def batch_recording(path: Path) -> Path | None:
    """The batch recording `path` names (a batch folder, or its recording.h5), else None."""
    from app.records.batch import is_batch_folder

    if path.is_dir():
        return path / "recording.h5" if is_batch_folder(path) else None
    if path.suffix.lower() in (".h5", ".hdf5") and is_batch_folder(path.parent):
        return path
    return None


def cmd_analyze_batch(args: argparse.Namespace, recording_path: Path) -> int:
    """Analyse every DUT channel of the batch recording at `recording_path`."""
    from app.io.hdf5 import RecordingError, read_recording
    from app.procedure.analysis import analyze
    from app.procedure.batch_files import batch_channels, channel_skew_s
    from app.records.batch import BatchError, read_batch

    for flag, given in (
        ("--csv", args.csv),
        ("--budget", args.budget),
        ("--reference-frequency", args.reference_frequency),
        ("--settle-periods", args.settle_periods),
        ("--mains", args.mains),
    ):
        if given is not None:
            raise UsageError(f"{flag}: not for a batch; analyse a member's run folder with it")
    folder = recording_path.parent
    try:
        batch = read_batch(folder)  # its seal and manifest checked first
    except BatchError as exc:
        raise RecordingError(str(exc)) from None
    members = {m.channel: m for m in batch.members}
    lead = batch.members[0].channel if batch.members else None
    out = []
    for channel in batch_channels(recording_path):
        recording = read_recording(recording_path, stored=True, dut_channel=channel)
        member = members.get(channel)
        own = folder.parent / member.run_id / "recording.h5" if member else None
        note = "its member run's budget"
        # a triaxial orientation's cross channel (dut.<p>.<axis> not the first member's):
        # as its member run stored it, else from the batch's order
        transverse = _cross_channel(channel, lead)
        if own is not None and own.exists():
            transverse = recorded_transverse(own)
            stored = read_recording(own, stored=True)  # its budget, and the truth it names
            recording = dataclasses.replace(
                recording, budget=stored.budget, truth=stored.truth, chain=stored.chain
            )  # its chain: its own channel's skew
        else:
            note = "the batch recording's budget (the member's run folder is not beside it)"
            skew = channel_skew_s(recording_path, channel)
            if skew is not None:  # the channel's own delay, as its member run used it
                chain = dataclasses.replace(recording.chain, skew_s=skew)
                recording = dataclasses.replace(recording, chain=chain)
        analysis = analyze(
            recording,
            estimator=_estimator(args, folder.parent / member.run_id if member else None),
            segments=args.segments,
            probability=args.coverage,
            rule="seed" if args.seed_rule else "gum",
            tolerance_percent=args.tolerance,
            mcm_trials=args.mcm,
            transverse=transverse,
        )
        out.append((channel, member, note, analysis))
    return _report(args, batch.batch_id, str(recording_path), out)


def _cross_channel(channel: str, lead: str | None) -> bool:
    """Whether `channel` of a batch recording whose first member's channel is `lead` is a
    triaxial sensor's cross channel: both channels of one triaxial position
    ("dut.<position>.<axis>", issue 36 point 3), not the first (the axis along the exciter)."""
    if lead is None or channel == lead:
        return False
    own, first = channel.split("."), lead.split(".")
    axes = ("x", "y", "z")
    return (
        len(own) == len(first) == 3 and own[1] == first[1] and own[2] in axes and first[2] in axes
    )


def _report(args: argparse.Namespace, batch_id: str | None, source: str, out: list) -> int:
    """Each DUT channel's results: as JSON (one row per channel) or printed in turn."""
    if args.json:
        rows = [
            {
                "channel": channel,
                "position": member.position if member else None,
                "serial": member.serial if member else None,
                "budget": note,
                "status": analysis.status or "unknown",
                **analysis.results.to_dict(),
            }
            for channel, member, note, analysis in out
        ]
        print(json.dumps({"batch_id": batch_id, "members": rows}, indent=2))
        return EXIT_OK
    for channel, member, note, analysis in out:
        serial = f", DUT {member.serial}" if member else ""
        print(f"--- {channel}{serial} ({note})")
        print_results(analysis.results, f"{source} {channel}", analysis.status)
    return EXIT_OK


def several_dut_recordings(args: argparse.Namespace) -> dict[str, Any] | None:
    """A CSV or TDMS recording of several DUTs (channels named dut.<position>, issue 36) as
    one two-channel recording per DUT channel (app.io.csv / app.io.tdms); None for any other
    file (read as today)."""
    from app.cli.options import plan_from_options, positive
    from app.cli.readers import _chain_and_budget
    from app.io.hdf5 import RecordingError

    suffix = args.file.suffix.lower()
    if args.file.is_dir() or suffix not in (".csv", ".txt", ".tdms"):
        return None
    if suffix == ".tdms":
        from app.io.tdms import inspect_tdms_channels, read_tdms_channels

        if args.dut is not None:
            return None
        try:
            source = inspect_tdms_channels(args.file, args.reference)
        except RecordingError:
            return None  # no channel named dut.<position>: a single-DUT file
        if set(source.duts) <= {"dut"}:
            return None
        positive("--sample-rate", args.sample_rate)
        rate = source.sample_rate_hz or args.sample_rate
        if rate is None:
            raise UsageError(
                f"--sample-rate: {args.file.name} states none (no wf_increment); give it in Hz"
            )
        chain, budget, cmc = _chain_and_budget(args, "TDMS")
        plan_args = argparse.Namespace(**{**vars(args), "sample_rate": rate})
        plan = plan_from_options(plan_args, optimise=False)
        recordings = read_tdms_channels(
            args.file, plan, chain, budget, reference=args.reference,
            settle_periods=args.settle_periods or 0, range_v=args.range_v, source=source,
        )  # fmt: skip
    else:
        from app.io.csv import read_csv_channels, several_dut_columns

        if not several_dut_columns(args.file):
            return None
        chain, budget, cmc = _chain_and_budget(args, "CSV")
        plan = plan_from_options(args, optimise=False)
        recordings = read_csv_channels(
            args.file, plan, chain, budget,
            settle_periods=args.settle_periods or 0, range_v=args.range_v,
        )  # fmt: skip
    return {name: dataclasses.replace(r, cmc=cmc) for name, r in recordings.items()}


def cmd_analyze_channels(args: argparse.Namespace, recordings: dict[str, Any]) -> int:
    """`analyze` of a several-DUT CSV or TDMS: each DUT channel by the same analysis."""
    from app.procedure.analysis import analyze
    from dsp.estimators import RECORDING_ESTIMATOR

    out = []
    for channel, recording in recordings.items():
        analysis = analyze(
            recording,
            estimator=str(args.estimator or RECORDING_ESTIMATOR),
            segments=args.segments,
            probability=args.coverage,
            rule="seed" if args.seed_rule else "gum",
            tolerance_percent=args.tolerance,
            mcm_trials=args.mcm,
        )
        out.append((channel, None, "the --budget given", analysis))
    return _report(args, None, str(args.file), out)


def _estimator(args: argparse.Namespace, member_run: Path | None) -> str:
    """--estimator when given; else the one the member's run used (its config.json), as a
    single run is re-analysed; else periodic."""
    from app.records.run_start import RunStart
    from dsp.estimators import RECORDING_ESTIMATOR

    if args.estimator is not None:
        return str(args.estimator)
    if args.segments is None and member_run is not None and member_run.is_dir():
        used = RunStart.read(member_run).settings.get("estimator")
        if used:
            return str(used)
    return str(RECORDING_ESTIMATOR)
