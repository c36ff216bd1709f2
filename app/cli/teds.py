"""`accelcal teds`: decode a TEDS file, read a sensor's TEDS, write a run's result to it.

`--channel dut.<position>` names one DUT input of the stand file's fixture (several DUTs in one
run, issue 36): on a real stand read through hardware.nidaq.read_teds_channels, on the
simulated one each position's sensor has its own TEDS. Without it: the stand's one DUT channel.

Writing names the sensor on the port (serial and model from its TEDS) and refuses one that is
not the run's DUT (the records' TEDS identity of the run's sensor, else the run's serial)
unless --yes-different-sensor REASON, which is logged and, with records, audited."""

from __future__ import annotations

import argparse
import sys

from app.cli.exits import EXIT_OK, UsageError


def cmd_teds(args: argparse.Namespace) -> int:
    """accelcal teds decode|read|write; writing asks first (or --yes) and reads back."""
    from app.procedure import teds_write
    from app.records.run_folder import load_run
    from app.stand import teds as teds_io
    from hardware.teds import TedsError, decode, read_ted_file

    db = getattr(args, "db", None)
    try:
        if args.teds_command == "decode":
            for line in teds_io.describe(decode(read_ted_file(args.file))):
                print(line)
            return EXIT_OK
        port = teds_io.open_port(args.stand, args.dut, args.seed, args.channel)
        if args.teds_command == "read":
            print(f"TEDS on {port.description}:")
            for line in teds_io.describe(decode(port.read())):
                print(f"  {line}")
            return EXIT_OK
        plan = teds_write.plan_write(port, load_run(args.run), args.initials, db)
    except (TedsError, ValueError) as exc:  # a run that does not verify is a ValueError too
        raise UsageError(str(exc)) from None
    print(f"sensor on {port.description}: {plan.sensor}")
    override = args.yes_different_sensor
    refused = plan.refusal(override)
    if refused is not None:
        raise UsageError(refused)
    if not args.yes:
        if not sys.stdin.isatty():
            raise UsageError("--yes: writing a TEDS needs a confirmation (a terminal, or --yes)")
        answer = input(f"Write to the TEDS on {port.description}: {plan.change}? [y/N] ")
        if answer.strip().lower() not in ("y", "yes"):
            print("TEDS not written")
            return EXIT_OK
    try:
        teds_write.write(plan, override, db, announce=_announce_override)
    except TedsError as exc:
        raise UsageError(str(exc)) from None
    print(f"TEDS written and read back on {port.description}: {plan.change}")
    return EXIT_OK


def _announce_override(line: str) -> None:
    """The override on stderr, before anything is written."""
    print(f"OVERRIDE {line}", file=sys.stderr)
