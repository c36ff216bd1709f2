"""The recording `accelcal analyze` reads, chosen by its file type: a run folder or HDF5
recording of this program (which stores its plan, chain and budget), a CSV or a TDMS file
(whose plan, reference chain and budget come from the options)."""

from __future__ import annotations

import argparse
import dataclasses
import math
import tomllib
from pathlib import Path
from typing import TYPE_CHECKING

from app.cli.exits import UsageError
from app.cli.options import plan_from_options, positive
from app.io.checks import MAX_TEXT_BYTES, InputFileError, check_input_file

if TYPE_CHECKING:
    from dsp.calibration import ReferenceChain
    from dsp.cmc import Cmc
    from dsp.estimators import Estimator
    from dsp.uncertainty import Budget


def load_recording(args: argparse.Namespace):
    from app.io.csv import read_csv
    from app.procedure.analysis import read_for_analysis, reanalysis
    from app.records.run_folder import is_run_folder

    if args.file.is_dir() and not is_run_folder(args.file):
        raise UsageError(
            f"{args.file}: is a folder but not a run folder (no manifest.json); name a "
            "recording file (.h5, .csv) or a run folder"
        )
    suffix = args.file.suffix.lower()
    if suffix in (".h5", ".hdf5") or args.file.is_dir():  # a run folder: its recording.h5
        given = [
            name
            for name in (
                "preset",
                "frequencies",
                "sample_rate",
                "period",
                "reference_sensitivity",
                "reference_gain",
                "dut_gain",
                "skew",
                "budget",
                "range_v",
                "level",
                "reference",
                "dut",
            )
            if getattr(args, name) not in (None, False)
        ]
        if given:
            opts = ", ".join("--" + g.replace("_", "-").replace("range-v", "range") for g in given)
            raise UsageError(f"{opts}: not allowed with an HDF5 recording, which stores them")
        positive("--reference-frequency", args.reference_frequency)
        positive("--mains", args.mains)
        return reanalysis(
            read_for_analysis(args.file),
            reference_frequency_hz=args.reference_frequency,
            settle_periods=args.settle_periods,
            mains_frequency_hz=args.mains,
        )
    if suffix == ".tdms":
        return _load_tdms(args)
    if suffix not in (".csv", ".txt"):
        raise UsageError(f"{args.file}: unknown recording type (use .h5/.hdf5, .csv or .tdms)")
    if args.reference is not None or args.dut is not None:
        raise UsageError(
            "--reference, --dut: TDMS channels; a CSV's columns are reference, DUT[, drive]"
        )
    if args.preset is None and (
        args.frequencies is None or args.sample_rate is None or args.period is None
    ):
        raise UsageError(
            "--preset, or --frequencies with --sample-rate and --period: a CSV recording "
            "needs its plan"
        )
    chain, budget, cmc = _chain_and_budget(args, "CSV")
    plan = plan_from_options(args, optimise=False)
    recording = read_csv(
        args.file,
        plan,
        chain,
        budget,
        settle_periods=args.settle_periods or 0,
        range_v=args.range_v,
    )
    return dataclasses.replace(recording, cmc=cmc)


def _load_tdms(args: argparse.Namespace):
    """A TDMS recording: the two channels the options name, the sample rate from the file."""
    from app.io.tdms import inspect_tdms, read_tdms

    if args.preset is None and (args.frequencies is None or args.period is None):
        raise UsageError(
            "--preset, or --frequencies with --period: a TDMS recording needs its plan (the "
            "sample rate comes from the file)"
        )
    source = inspect_tdms(args.file, args.reference, args.dut)
    rate = source.sample_rate_hz
    positive("--sample-rate", args.sample_rate)
    if rate is None and args.sample_rate is None:
        raise UsageError(
            f"--sample-rate: {args.file.name} states none (no wf_increment); give it in Hz"
        )
    if rate is not None and args.sample_rate is not None:
        if not math.isclose(args.sample_rate, rate, rel_tol=1e-9):
            raise UsageError(
                f"--sample-rate: {args.sample_rate:g} Hz disagrees with {args.file.name}'s "
                f"{rate:g} Hz (1 / wf_increment)"
            )
    chain, budget, cmc = _chain_and_budget(args, "TDMS")
    plan_args = argparse.Namespace(**{**vars(args), "sample_rate": rate or args.sample_rate})
    plan = plan_from_options(plan_args, optimise=False)
    recording = read_tdms(
        args.file,
        plan,
        chain,
        budget,
        reference=args.reference,
        dut=args.dut,
        settle_periods=args.settle_periods or 0,
        range_v=args.range_v,
        source=source,
    )
    return dataclasses.replace(recording, cmc=cmc)


def _chain_and_budget(
    args: argparse.Namespace, kind: str
) -> tuple[ReferenceChain, Budget, Cmc | None]:
    """The reference chain, budget and CMC of a CSV or TDMS recording, from the options."""
    from dsp.calibration import ReferenceChain
    from dsp.uncertainty import Budget

    if args.reference_sensitivity is None:
        raise UsageError(f"--reference-sensitivity: a {kind} recording needs it (mV/(m/s^2))")
    for name in ("reference_sensitivity", "reference_gain", "dut_gain", "sample_rate", "range_v"):
        positive("--" + name.replace("_", "-"), getattr(args, name))
    if args.settle_periods is not None and args.settle_periods < 0:
        raise UsageError(f"--settle-periods: must be >= 0, got {args.settle_periods}")
    chain = ReferenceChain.flat(
        args.reference_sensitivity,
        reference_gain=args.reference_gain or 1.0,
        dut_gain=args.dut_gain or 1.0,
        skew_s=args.skew,  # None: from the file (header line, property), else unknown
    )
    if not args.budget:
        return chain, Budget(()), None
    return (chain, *_read_budget(args.budget))


def _read_budget(path: Path) -> tuple[Budget, Cmc | None]:
    """--budget: its [[component]] tables (each plausible, one Annex A kind each) and its
    optional [[cmc]] tables (the laboratory's CMC, dsp.cmc); UsageError naming what is wrong."""
    from dsp.annex_a import implausible_components
    from dsp.cmc import Cmc
    from dsp.uncertainty import Budget

    try:
        check_input_file(path, MAX_TEXT_BYTES, "budget file")
    except InputFileError as exc:
        raise UsageError(f"--budget: {exc}") from None
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise UsageError(f"--budget: {path}: no such file") from None
    except tomllib.TOMLDecodeError as exc:
        raise UsageError(f"--budget: {path}: {exc}") from None
    entries = data.get("component")
    if not isinstance(entries, list):
        raise UsageError(f"--budget: {path}: expected [[component]] tables")
    try:
        budget = Budget.from_list(entries)
        cmc_entries = data.get("cmc")
        if cmc_entries is not None and not isinstance(cmc_entries, list):
            raise ValueError("cmc: must be [[cmc]] tables")
        cmc = Cmc.from_list(cmc_entries) if cmc_entries is not None else None
    except ValueError as exc:
        raise UsageError(f"--budget: {path}: {exc}") from None
    refused = implausible_components(budget)
    if refused:
        raise UsageError(f"--budget: {path}: component refused: {'; '.join(refused)}")
    return budget, cmc


def recorded_estimator(args: argparse.Namespace) -> Estimator:
    """The estimator `accelcal analyze` uses: `--estimator` when given; else the one a run
    folder's config.json names (written before anything moved, so an interrupted run has it
    too; a run from before the setting: periodic, as results.json is read); else, and with
    `--segments` (the seed's protocol averages), RECORDING_ESTIMATOR (periodic). A stored run
    is re-analysed as it was run, whatever the default of new runs."""
    from app.records.run_folder import is_run_folder
    from app.records.run_record import AnalysisSettings
    from app.records.run_start import CONFIG_NAME, RunStart
    from dsp.estimators import RECORDING_ESTIMATOR, Estimator

    if args.estimator is not None:
        return Estimator(args.estimator)
    path = Path(args.file)
    folder = path if path.is_dir() else path.parent
    if args.segments is not None or not is_run_folder(folder):
        return RECORDING_ESTIMATOR
    try:
        start = RunStart.from_json((folder / CONFIG_NAME).read_text(encoding="utf-8"))
        return AnalysisSettings.from_dict(start.settings).estimator
    except (OSError, ValueError):  # no readable config.json (or its settings): none named
        return RECORDING_ESTIMATOR


def recorded_transverse(path: Path) -> bool:
    """Whether the run folder `path` names (a run folder, or its recording) is a triaxial
    sensor's cross channel, as its config.json's batch link stores it (issue 36 point 3): it
    is then analysed as the run analysed it (no dead-channel refusal, no verdict). False for
    any other file (a CSV, TDMS, a recording outside a run folder)."""
    from app.records.run_folder import is_run_folder
    from app.records.run_start import RunStart

    folder = path if path.is_dir() else path.parent
    if not is_run_folder(folder):
        return False
    link = RunStart.read(folder).batch  # RunStartError (exit 2) naming the file: unreadable
    return link is not None and link.transverse
