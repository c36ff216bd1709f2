"""`accelcal show`: print a stored run."""

from __future__ import annotations

import argparse
import json

from app.cli.exits import EXIT_OK, UsageError
from app.cli.printers import print_results


def cmd_show(args: argparse.Namespace) -> int:
    from app.records.run_folder import load_run

    try:
        record = load_run(args.run)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    if args.json:
        print(json.dumps(record.to_dict(), indent=2))
        return EXIT_OK
    print(
        f"run {record.run_id}: {record.status}"
        + (f" ({record.abort_reason})" if record.abort_reason else "")
    )
    print(
        f"started {record.started_utc}, finished {record.finished_utc}, "
        f"excitation {record.excitation_time_s:.1f} s, raw data SHA-256 "
        f"{record.raw_data_sha256 or 'n/a'}"
    )
    results = record.results_object()
    if results is not None:
        print_results(results, str(args.run))
    return EXIT_OK
