"""`accelcal simulate`: record a calibration on the simulated stand, or list its catalogue."""

from __future__ import annotations

import argparse
import json
import sys

from app.cli.exits import EXIT_ABORTED, EXIT_OK, UsageError
from app.cli.options import faults_option, writable_folder
from app.cli.printers import print_catalogue
from app.stand.simulated import catalogue_entries
from hardware.errors import HardwareError


def cmd_simulate(args: argparse.Namespace) -> int:
    import app.procedure.simulate as simulation  # h5py: only when recording

    if args.list:
        print_catalogue(catalogue_entries(), args.json)
        return EXIT_OK
    if args.out is None:
        raise UsageError("--out: the recording to write is required (or --list)")
    if args.out.suffix.lower() not in (".h5", ".hdf5"):
        raise UsageError(f"--out: {args.out} must end in .h5 or .hdf5")
    faults = faults_option(args.fault)
    writable_folder(args.out.parent, "--out")
    try:
        run = simulation.simulate(
            args.out,
            dut=args.dut,
            level_ms2=args.level,
            periods=args.periods,
            seed=args.seed,
            settle=args.settle,
            faults=faults,
            overwrite=args.overwrite,
        )
    except HardwareError as exc:  # an aborted recording: exit 3, as an aborted run (README)
        print(f"accelcal simulate: {type(exc).__name__}: {exc}", file=sys.stderr)
        print(
            f"accelcal simulate: the recording so far, marked aborted: {args.out}", file=sys.stderr
        )
        return EXIT_ABORTED
    summary = {
        "recording": str(run.path),
        "dut": args.dut,
        "level_ms2": args.level,
        "periods": run.periods,
        "settle_periods": run.settle_periods,
        "sample_rate_hz": run.plan.sample_rate_hz,
        "period_samples": run.plan.period_samples,
        "drive_peak_v": run.drive_peak_v,
        "ranges_v": run.ranges_v,
        "seed": args.seed,
    }
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        print(
            f"wrote {run.path}: {args.dut} at {args.level:g} m/s^2 per line, "
            f"{run.settle_periods} settling + {run.periods} periods of {run.plan.period_s:g} s "
            f"at {run.plan.sample_rate_hz:g} Hz; drive peak {run.drive_peak_v:.2f} V; "
            f"ranges reference +-{run.ranges_v['reference']:g} V, dut +-{run.ranges_v['dut']:g} V"
        )
    return EXIT_OK
