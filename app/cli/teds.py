"""`accelcal teds`: decode a TEDS file, read a sensor's TEDS, write a run's result to it.

Writing names the sensor on the port (serial and model from its TEDS) and refuses one that is
not the run's DUT (the records' TEDS identity of the run's sensor, else the run's serial)
unless --yes-different-sensor REASON, which is logged and, with records, audited."""

from __future__ import annotations

import argparse
import logging
import sys
from typing import Any

from app.cli.exits import EXIT_OK, UsageError

log = logging.getLogger(__name__)


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
        present = decode(current)
    except (TedsError, ValueError) as exc:  # a run that does not verify is a ValueError too
        raise UsageError(str(exc)) from None
    assert new.accelerometer is not None
    print(f"sensor on {port.description}: {teds_io.sensor_named(present)}")
    mismatch = teds_io.identity_mismatch(present, record, _records_identity(args, record))
    override = (args.yes_different_sensor or "").strip()
    if mismatch is not None:
        if not override:
            raise UsageError(
                f"teds write: {mismatch}; not written (a different sensor, if meant: "
                "--yes-different-sensor REASON)"
            )
    old = present.accelerometer
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
    if mismatch is not None:
        _record_override(args, record, mismatch, override)  # before the write, never after
    try:
        teds_io.write_checked(port, new)
    except TedsError as exc:
        raise UsageError(str(exc)) from None
    print(f"TEDS written and read back on {port.description}: {change}")
    return EXIT_OK


def _records_identity(args: argparse.Namespace, record: Any) -> str | None:
    """The TEDS identity the records keep for the run's sensor (None: no records in use, the
    sensor is not on record or has none)."""
    from app.records.db.engine import records_url

    url = records_url(getattr(args, "db", None))
    serial = (record.dut.id if record.dut else None) or ""
    if url is None or not serial:
        return None
    from app.records.db.engine import open_engine
    from app.records.db.lab import Lab
    from app.records.db.store import RecordsError

    try:
        return Lab(open_engine(url)).sensor(serial).teds_identity or None
    except RecordsError:
        return None


def _record_override(args: argparse.Namespace, record: Any, mismatch: str, reason: str) -> None:
    """The override logged (the run folder is sealed: its log is never appended to) and, with
    records in use, entered in their audit trail."""
    line = (
        f"teds write to a different sensor for run {record.run_id}: {mismatch}; override: {reason}"
    )
    log.warning("%s", line)
    print(f"OVERRIDE {line}", file=sys.stderr)
    from app.records.db.engine import records_url

    url = records_url(getattr(args, "db", None))
    if url is not None:
        from app.records.db.engine import open_engine
        from app.records.db.lab import Lab

        Lab(open_engine(url)).note_override(
            str(record.run_id), "teds write: different sensor", f"{mismatch}; reason: {reason}"
        )
