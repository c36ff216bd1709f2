"""`accelcal show`: print a stored run; given a folder of runs (the runs root), list them."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from app.cli.exits import EXIT_OK, UsageError
from app.cli.printers import print_results


def cmd_show(args: argparse.Namespace) -> int:
    from app.records.batch import is_batch_folder
    from app.records.run_folder import is_run_folder, load_run

    folder = Path(args.run)
    if not folder.exists() and is_batch_folder(Path("runs") / folder):  # a batch id
        folder = Path("runs") / folder
    if is_batch_folder(folder):
        return _show_batch(folder, args.json)
    if folder.is_dir() and not is_run_folder(folder):
        runs = sorted(p for p in folder.iterdir() if p.is_dir() and is_run_folder(p))
        if runs:
            return _list_runs(folder, runs, args.json)
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


def _list_runs(root: Path, runs: list[Path], as_json: bool) -> int:
    """A folder of run folders: what it is, and each run with its verified state."""
    from app.records.run_folder import inspect_run

    rows = []
    for path in runs:
        check = inspect_run(path)
        record = check.record
        rows.append(
            {
                "run": path.name,
                "state": str(check.state),
                "dut_id": record.dut.id if record is not None and record.dut else None,
                "started_utc": record.started_utc if record is not None else None,
            }
        )
    if as_json:
        print(json.dumps({"runs_root": str(root), "runs": rows}, indent=2))
        return EXIT_OK
    print(
        f"{root}: a folder of {len(rows)} run(s), not a run folder; "
        "`accelcal show RUN_FOLDER` shows one:"
    )
    width = max(len(str(r["run"])) for r in rows)
    for r in rows:
        print(f"  {r['run']:<{width}}  {r['state']:<11}  {r['dut_id'] or ''}".rstrip())
    return EXIT_OK


def _show_batch(folder: Path, as_json: bool) -> int:
    """A batch folder (several DUTs in one run): its seal checked, each member's run with its
    verified state and verdict."""
    from app.cli.readers import recorded_transverse
    from app.records.batch import BatchError, read_batch
    from app.records.run_folder import inspect_run

    try:
        batch = read_batch(folder)
    except BatchError as exc:
        raise UsageError(str(exc)) from None
    rows = []
    for member in batch.members:
        check = inspect_run(folder.parent / member.run_id)
        record = check.record
        row: dict[str, str | bool | None] = {
            "position": member.position,
            "channel": member.channel,
            "serial": member.serial,
            "run_id": member.run_id,
            "state": str(check.state),
            "verdict": str(record.verdict) if record is not None and record.verdict else None,
            "seal_sha256": member.seal_sha256,
        }
        if member.channel.count(".") == 2:  # a triaxial DUT's channel: its axis's role
            row["transverse"] = recorded_transverse(folder.parent / member.run_id)
        rows.append(row)
    if as_json:
        print(
            json.dumps(
                {
                    "batch_id": batch.batch_id,
                    "fixture": batch.fixture,
                    "status": batch.status,
                    "members": rows,
                },
                indent=2,
            )
        )
        return EXIT_OK
    print(f"batch {batch.batch_id}: {batch.status}, {len(rows)} DUTs on {batch.fixture}")
    print(f"started {batch.started_utc}")
    for r in rows:
        where = r["position"]
        verdict = r["verdict"] or ""
        if "transverse" in r:  # a triaxial DUT: its channels' axes, the cross ones no verdict
            where = str(r["channel"]).removeprefix("dut.")
            verdict = "cross channel, no verdict" if r["transverse"] else verdict
        print(f"  {where:<6} {r['serial']:<16} {r['run_id']}  {r['state']:<9} {verdict}".rstrip())
    return EXIT_OK
