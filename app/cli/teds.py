"""`accelcal teds`: decode a TEDS file, read a sensor's TEDS, write a run's result to it."""

from __future__ import annotations

import argparse
import sys

from app.cli.exits import EXIT_OK, UsageError


def cmd_teds(args: argparse.Namespace) -> int:
    """accelcal teds decode|read|write; writing asks first (or --yes) and reads back."""
    from app.records.run_folder import load_run
    from app.stand import teds as teds_io
    from hardware.teds import TedsError, decode, read_ted_file

    try:
        if args.teds_command == "decode":
            for line in teds_io.describe(decode(read_ted_file(args.file))):
                print(line)
            return EXIT_OK
        port = teds_io.open_port(args.stand, args.dut, args.seed)
        current = port.read()
        if args.teds_command == "read":
            print(f"TEDS on {port.description}:")
            for line in teds_io.describe(decode(current)):
                print(f"  {line}")
            return EXIT_OK
        record = load_run(args.run)
        new = teds_io.calibrated_teds(current, record, args.initials)
    except (TedsError, ValueError) as exc:  # a run that does not verify is a ValueError too
        raise UsageError(str(exc)) from None
    assert new.accelerometer is not None
    old = decode(current).accelerometer
    change = (
        f"sensitivity {old.sensitivity_mv_per_ms2 if old else float('nan'):.5g} -> "
        f"{new.accelerometer.sensitivity_mv_per_ms2:.5g} mV/(m/s^2), calibration date "
        f"{new.accelerometer.calibration_date} (run {record.run_id})"
    )
    if not args.yes:
        if not sys.stdin.isatty():
            raise UsageError("--yes: writing a TEDS needs a confirmation (a terminal, or --yes)")
        answer = input(f"Write to the TEDS on {port.description}: {change}? [y/N] ")
        if answer.strip().lower() not in ("y", "yes"):
            print("TEDS not written")
            return EXIT_OK
    teds_io.write_checked(port, new)
    print(f"TEDS written and read back on {port.description}: {change}")
    return EXIT_OK
