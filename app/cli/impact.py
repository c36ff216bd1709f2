"""`accelcal impact REF-SERIAL --table corrected.csv [--since DATE]`: the impact of a reference
standard found out of tolerance (app.procedure.impact): re-analysis of every run that used it,
the impact report (CSV, PDF), a draft notice per customer, certificates flagged under review."""

from __future__ import annotations

import argparse
import os
import re
import sys
from datetime import UTC, datetime, time

from app.cli.exits import EXIT_OK, UsageError
from app.files import write_new


def _since(args: argparse.Namespace, lab) -> datetime | None:  # type: ignore[no-untyped-def]
    """--since, else the calibration date of the reference on record (its last good
    calibration), else None (every indexed run)."""
    if args.since is not None:
        return datetime.combine(args.since, time.min, UTC)
    wanted = args.serial.strip().casefold()
    for ref in lab.references():
        if wanted in (ref.identifier.casefold(), ref.serial.casefold()):
            return datetime.combine(ref.calibration_date, time.min, UTC)
    return None


def _safe_name(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9._-]+", "_", text).strip("_")[:80] or "unnamed"


def cmd_impact(args: argparse.Namespace) -> int:
    from app.cli.records import _lab
    from app.procedure import impact, impact_report

    if args.workers is not None and not 1 <= args.workers <= 64:  # also bounded by the parser
        raise UsageError(f"--workers: must be 1 to 64, got {args.workers}")
    table = impact.read_table(args.table)
    out = args.out or _default_out(args.serial)
    if out.exists() and any(out.iterdir()):
        raise UsageError(f"--out: {out} exists and is not empty (a report is never overwritten)")
    lab = _lab(args)
    since = _since(args, lab)
    until = None if args.until is None else datetime.combine(args.until, time.max, UTC)
    if since is not None and until is not None and until < since:
        raise UsageError(f"--until: {args.until} is before the window's start {since.date()}")
    runs = lab.runs_between(since, until)
    tasks = [
        impact.Task(
            r.run_id, r.folder, r.manifest_sha256, r.started_utc, r.dut_id, r.owner, r.certificates
        )
        for r in runs
    ]
    workers = args.workers or min(len(tasks), os.cpu_count() or 1) or 1

    def progress(done: int, total: int, elapsed: float) -> None:
        print(impact.progress_line(done, total, elapsed), file=sys.stderr, flush=True)

    checked = impact.assess(tasks, args.serial, table, workers=workers, progress=progress)
    affected = tuple(r for r in checked if r.uses_reference)
    flagged: list[str] = []
    if not args.no_flag:
        subject = impact.review_subject(args.serial)
        for r in affected:
            for number in r.task.certificates:
                reason = impact.review_reason(args.serial, r, table)
                if lab.open_review(number, subject=subject, reason=reason):
                    flagged.append(number)
    report = impact_report.ImpactReport(
        args.serial, table, since, until, affected, tuple(flagged), len(tasks)
    )
    out.mkdir(parents=True, exist_ok=True)
    name = _safe_name(args.serial)
    write_new(out / f"impact-{name}.csv", impact_report.to_csv(report))
    write_new(out / f"impact-{name}.pdf", impact_report.to_pdf(report))
    for owner, text in impact_report.notices(report).items():
        write_new(out / f"notice-{_safe_name(owner)}.txt", text)
    for line in impact_report.summary_lines(report):
        print(line)
    for r in affected:
        if r.problem:
            print(f"{r.task.run_id}\tNOT CHECKED: {r.problem}")
            continue
        verdict = f"{r.old_verdict} -> {r.new_verdict}" if r.verdict_changed else r.new_verdict
        change = "n/a" if r.change_in_u is None else f"{r.change_in_u:+.2f} U"
        print(
            f"{r.task.run_id}\t{r.task.dut_id}\t{r.reference_frequency_hz:g} Hz\t"
            f"{r.old_sensitivity:.6g} -> {r.new_sensitivity:.6g} mV/(m/s^2)\t{change}\t"
            f"{verdict}\t{' '.join(r.task.certificates) or '-'}"
        )
    print(f"report: {out}")
    return EXIT_OK


def _default_out(serial: str):  # type: ignore[no-untyped-def]
    from pathlib import Path

    stamp = datetime.now(UTC).strftime("%Y%m%dT%H%M%SZ")
    return Path(f"impact-{_safe_name(serial)}-{stamp}")
