"""The records commands of `accelcal`: db, customers, models, sensors, refs, due, history,
register. Thin: each parses its options, calls app.records.db.lab and prints. SQLAlchemy is imported
only when one of these commands runs (app.cli stays quick to start)."""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable
from datetime import UTC, date, datetime
from pathlib import Path
from typing import TYPE_CHECKING

from app.cli.db_verify import add_verify, cmd_db_verify
from app.cli.listing import (
    certificate_row,
    control_row,
    customer_row,
    due_row,
    history_object,
    model_row,
    print_rows,
    reference_row,
    sensor_row,
)
from app.cli.options import FREQUENCY, LEVEL, TOLERANCE, Bounded, numeric_option
from app.cli.reviews import REVIEW_ACTIONS, add_review_commands
from app.cli.toplevel import RECORDS_COMMAND_NAMES
from app.io.quantities import PERCENT_RULE
from app.records.db.errors import RecordsInputError

if TYPE_CHECKING:
    from app.records.db.lab import Lab

Handler = Callable[[argparse.Namespace], int]

NOMINAL = Bounded(float, 0.0, 1e6, open_low=True)
PHASE_TOLERANCE = Bounded(float, 0.0, 180.0, open_low=True, unit="deg")
INTERVAL = Bounded(int, 1, 120, unit="months")
DAYS = Bounded(int, 0, 3650, unit="days")


class RecordsUsageError(RecordsInputError):
    """A records option that cannot be used; the message names it."""


def _iso_date(field: str) -> Callable[[str], date]:
    def parse(text: str) -> date:
        try:
            return date.fromisoformat(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{field}: not a date yyyy-mm-dd: {text!r}") from None

    return parse


def _lab(args: argparse.Namespace) -> Lab:
    from app.records.db.engine import open_engine
    from app.records.db.lab import Lab

    return Lab(open_engine(args.db))


def _db_option(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--db", metavar="URL", help="records database (default $ACCELCAL_DB, else SQLite file)"
    )


def _list_options(p: argparse.ArgumentParser) -> None:
    """--db and --json of a list command."""
    p.add_argument(
        "--json",
        action="store_true",
        help="a JSON array of objects (stable keys, ISO 8601 dates, numbers as numbers)",
    )
    _db_option(p)


# the records commands' names (app.cli.toplevel: known before any parser is built);
# `add_commands` returns exactly these
COMMAND_NAMES = RECORDS_COMMAND_NAMES


def add_commands(sub: argparse._SubParsersAction) -> dict[str, Handler]:  # type: ignore[type-arg]
    """Add the records commands to the top-level subparsers; their handlers by name."""
    d = sub.add_parser("db", help="records database: upgrade (create or migrate), import runs")
    dsub = d.add_subparsers(dest="db_command", required=True, metavar="ACTION")
    up = dsub.add_parser("upgrade", help="create the schema or migrate it to this version")
    _db_option(up)
    im = dsub.add_parser("import", help="index run folders (verified ones only)")
    im.add_argument("folder", type=Path, help="a runs folder or one run folder")
    _db_option(im)
    add_verify(dsub)

    c = sub.add_parser("customers", help="customers: add, list")
    csub = c.add_subparsers(dest="action", required=True, metavar="ACTION")
    ca = csub.add_parser("add", help="add a customer")
    ca.add_argument("name")
    ca.add_argument("--address", default="")
    _db_option(ca)
    _list_options(csub.add_parser("list", help="list customers"))

    m = sub.add_parser("models", help="sensor models: add, list")
    msub = m.add_subparsers(dest="action", required=True, metavar="ACTION")
    ma = msub.add_parser("add", help="add a sensor model")
    ma.add_argument("maker")
    ma.add_argument("model")
    numeric_option(ma, "--nominal", NOMINAL, "nominal sensitivity in --unit", required=True)
    ma.add_argument("--unit", required=True, help="mV/(m/s^2), pC/(m/s^2) or mV/g")
    numeric_option(
        ma, "--tolerance", TOLERANCE, f"tolerance, {PERCENT_RULE.replace('%', '%%')}", required=True
    )
    numeric_option(ma, "--fmin", FREQUENCY, "lowest frequency", required=True)
    numeric_option(ma, "--fmax", FREQUENCY, "highest frequency", required=True)
    ma.add_argument("--preset", default="piezo", help="default plan")
    numeric_option(ma, "--level", LEVEL, "default level, e.g. 5 or 0.5g", default=5.0)
    numeric_option(ma, "--phase-tolerance", PHASE_TOLERANCE, "phase tolerance")
    _db_option(ma)
    _list_options(msub.add_parser("list", help="list sensor models"))

    s = sub.add_parser("sensors", help="sensors: add, list, show, move")
    ssub = s.add_subparsers(dest="action", required=True, metavar="ACTION")
    sa = ssub.add_parser("add", help="add a sensor")
    sa.add_argument("serial")
    sa.add_argument("--model", required=True, help="'maker model' or the model alone")
    sa.add_argument("--owner", required=True, help="customer name")
    numeric_option(sa, "--interval", INTERVAL, "calibration interval", default=12)
    sa.add_argument("--teds", help="TEDS identity (manufacturer/model/serial)")
    sa.add_argument(
        "--check-standard", action="store_true", help="the lab's check standard (control chart)"
    )
    _db_option(sa)
    sl = ssub.add_parser("list", help="list sensors")
    sl.add_argument("--search", default="", help="part of the serial")
    _list_options(sl)
    sw = ssub.add_parser("show", help="one sensor and its last calibration")
    sw.add_argument("serial")
    _db_option(sw)
    sm = ssub.add_parser(
        "move", help="give a sensor to another customer (its certificates stay with theirs)"
    )
    sm.add_argument("serial")
    sm.add_argument("--owner", required=True, help="the new owner's customer name")
    _db_option(sm)

    r = sub.add_parser("refs", help="reference standards: add, list, dcc")
    rsub = r.add_subparsers(dest="action", required=True, metavar="ACTION")
    ra = rsub.add_parser("add", help="add a reference standard with its calibration table")
    ra.add_argument("identifier")
    ra.add_argument("--model", help="required with --table; with --dcc, the DCC's by default")
    ra.add_argument("--serial", help="required with --table; with --dcc, must be the DCC's")
    ra.add_argument(
        "--certificate",
        help="its calibration certificate number (required with --table; with --dcc, the DCC's "
        "uniqueIdentifier)",
    )
    ra.add_argument(
        "--calibrated",
        type=_iso_date("--calibrated"),
        help="required with --table; with --dcc, the DCC's endPerformanceDate",
    )
    ra.add_argument("--due", type=_iso_date("--due"), required=True)
    source = ra.add_mutually_exclusive_group(required=True)
    source.add_argument(
        "--table",
        type=Path,
        help="CSV: frequency_hz,sensitivity_mv_per_ms2,relative_expanded_uncertainty_percent"
        "[,phase_deg]; the uncertainty in percent (0.5 means 0.5 %%); the header is optional, "
        "an uncertainty column not named in percent is refused",
    )
    source.add_argument(
        "--dcc",
        type=Path,
        metavar="FILE",
        help="its calibrating laboratory's DCC (PTB DCC 3.x XML): validated, its signature "
        "verified, its sensitivity table, dates, laboratory and item read; kept in the records "
        "with its SHA-256, which every certificate made with the reference names",
    )
    ra.add_argument(
        "--dcc-certificate",
        type=Path,
        metavar="PEM",
        help="the DCC signer's X.509 certificate to verify its signature against (default: "
        "the certificate the signature embeds)",
    )
    _db_option(ra)
    _list_options(rsub.add_parser("list", help="list reference standards"))
    rd = rsub.add_parser("dcc", help="write the DCC kept of a reference standard to a file")
    rd.add_argument("identifier")
    rd.add_argument("--out", type=Path, required=True, help="the file to write (never overwritten)")
    _db_option(rd)

    due = sub.add_parser("due", help="sensors and reference standards due for calibration")
    numeric_option(due, "--days", DAYS, "horizon (default 30)", default=30)
    _list_options(due)

    h = sub.add_parser("history", help="a sensor's calibrations over time and its drift")
    h.add_argument("serial")
    h.add_argument("--plot", type=Path, help="write a drift chart (PNG) here")
    h.add_argument(
        "--json", action="store_true", help="one JSON object: serial, points, drift (scripts)"
    )
    _db_option(h)

    k = sub.add_parser("control", help="a check standard's control chart on each stand")
    k.add_argument("serial")
    _list_options(k)

    g = sub.add_parser(
        "register", help="the certificate register: list, withdraw, review, reviews, set"
    )
    gsub = g.add_subparsers(dest="action", required=True, metavar="ACTION")
    _list_options(gsub.add_parser("list", help="every certificate, issued, replaced, withdrawn"))
    # `register issue` (a number without its PDF) was removed: `accelcal certificate RUN`
    # numbers, writes the PDF and DCC and enters them in one step; the name stays to say so
    gi = gsub.add_parser("issue", help="removed: use `accelcal certificate RUN_FOLDER`")
    gi.add_argument("rest", nargs=argparse.REMAINDER, help=argparse.SUPPRESS)
    gw = gsub.add_parser("withdraw", help="withdraw a certificate")
    gw.add_argument("number")
    gw.add_argument("--reason", required=True)
    _db_option(gw)
    add_review_commands(gsub, _db_option, _list_options)
    gs = gsub.add_parser("set", help="lab settings: certificate_pattern, two_person_rule")
    gs.add_argument("key", choices=("certificate_pattern", "two_person_rule"))
    gs.add_argument("value")
    _db_option(gs)

    return {
        "db": cmd_db,
        "customers": cmd_customers,
        "models": cmd_models,
        "sensors": cmd_sensors,
        "refs": cmd_refs,
        "due": cmd_due,
        "history": cmd_history,
        "register": cmd_register,
        "control": cmd_control,
    }


def cmd_db(args: argparse.Namespace) -> int:
    from app.records.db.engine import make_engine, resolve_url, upgrade
    from app.records.db.gate import records_quick_check

    if args.db_command == "upgrade":
        url = resolve_url(args.db)
        engine = make_engine(url)
        before, after = upgrade(engine)
        shown = engine.url.render_as_string(hide_password=True)
        if before == after:
            print(f"{shown}: schema already at {after}")
        else:
            print(f"{shown}: schema {before or 'none'} -> {after}")
        from app.records.db.records_key import require_key

        key = require_key()
        print(f"records key: {key.path} (id {key.key_id[:16]}...; keep it outside the database)")
        return 0
    if args.db_command == "verify":
        return cmd_db_verify(args)
    if not args.folder.is_dir():
        raise RecordsUsageError(f"folder: no such folder {args.folder}")
    records_quick_check(args.db)
    report = _lab(args).import_runs(args.folder)
    for run_id in report.imported:
        print(f"imported  {run_id}")
    for run_id in report.known:
        print(f"known     {run_id}")
    for folder, why in report.refused:
        print(f"refused   {folder}: {why}")
    for warning in report.warnings:
        print(f"WARNING   {warning}")
    print(
        f"{len(report.imported)} imported, {len(report.known)} already indexed, "
        f"{len(report.refused)} refused"
    )
    return 0


def cmd_customers(args: argparse.Namespace) -> int:
    lab = _lab(args)
    if args.action == "add":
        print(f"customer {lab.add_customer(args.name, args.address).name} added")
        return 0
    customers = lab.customers()
    if args.json:
        print_rows(customer_row(c) for c in customers)
        return 0
    for customer in customers:
        print(customer.name)
    return 0


def cmd_models(args: argparse.Namespace) -> int:
    lab = _lab(args)
    if args.action == "add":
        row = lab.add_model(
            args.maker,
            args.model,
            nominal_sensitivity=args.nominal,
            unit=args.unit,
            tolerance_percent=args.tolerance,
            frequency_min_hz=args.fmin,
            frequency_max_hz=args.fmax,
            preset=args.preset,
            level_ms2=args.level,
            phase_tolerance_deg=args.phase_tolerance,
        )
        print(f"model {row.maker} {row.model} added")
        return 0
    models = lab.models()
    if args.json:
        print_rows(model_row(m) for m in models)
        return 0
    for m in models:
        print(
            f"{m.maker} {m.model}: {m.nominal_sensitivity:g} {m.unit} "
            f"±{m.tolerance_percent:g} %, {m.frequency_min_hz:g}-{m.frequency_max_hz:g} Hz"
        )
    return 0


def cmd_sensors(args: argparse.Namespace) -> int:
    lab = _lab(args)
    if args.action == "add":
        row = lab.add_sensor(
            args.serial,
            model=args.model,
            owner=args.owner,
            interval_months=args.interval,
            teds_identity=args.teds,
            check_standard=args.check_standard,
        )
        print(f"sensor {row.serial} ({row.model.maker} {row.model.model}) added")
        return 0
    if args.action == "list":
        sensors = lab.sensors(args.search)
        if args.json:
            print_rows(sensor_row(s) for s in sensors)
            return 0
        for row in sensors:
            print(f"{row.serial}\t{row.model.maker} {row.model.model}\t{row.owner.name}")
        return 0
    if args.action == "move":
        lab.move_sensor(args.serial, owner=args.owner)
        print(
            f"sensor {args.serial} now owned by {args.owner.strip()}; its certificates stay "
            "with the customers they were issued to"
        )
        return 0
    row = lab.sensor(args.serial)
    history = lab.history(args.serial)
    print(f"serial:     {row.serial}")
    print(f"model:      {row.model.maker} {row.model.model}")
    print(f"nominal:    {row.model.nominal_sensitivity:g} {row.model.unit}")
    print(f"tolerance:  ±{row.model.tolerance_percent:g} %")
    print(f"owner:      {row.owner.name}")
    print(f"interval:   {row.interval_months} months")
    last = history.points[-1] if history.points else None
    print(f"last run:   {last.run_id if last else 'none on record'}")
    return 0


def cmd_refs(args: argparse.Namespace) -> int:
    if args.action == "add" and args.dcc is not None:
        from app.cli.reference_dcc import add_from_dcc

        return add_from_dcc(args, lambda: _lab(args))
    lab = _lab(args)
    if args.action == "dcc":
        from app.cli.reference_dcc import write_kept

        return write_kept(args, lab)
    if args.action == "add":
        from app.records.db.reference_table import read_reference_table

        if args.dcc_certificate is not None:
            raise RecordsUsageError("--dcc-certificate: goes with --dcc")
        for option in ("model", "serial", "certificate", "calibrated"):
            if getattr(args, option) is None:
                raise RecordsUsageError(f"--{option}: required with --table")
        table = read_reference_table(args.table)
        row = lab.add_reference(
            args.identifier,
            model=args.model,
            serial=args.serial,
            certificate_number=args.certificate,
            calibration_date=args.calibrated,
            due_date=args.due,
            table=table,
        )
        print(f"reference {row.identifier} added ({len(table)} table rows, due {row.due_date})")
        return 0
    references = lab.references()
    if args.json:
        print_rows(reference_row(r) for r in references)
        return 0
    for ref in references:
        print(
            f"{ref.identifier}\t{ref.model} {ref.serial}\t{ref.certificate_number}\t"
            f"calibrated {ref.calibration_date}\tdue {ref.due_date}\t{len(ref.points)} rows"
        )
    return 0


def cmd_due(args: argparse.Namespace) -> int:
    today = datetime.now(UTC).date()
    items = _lab(args).due(today=today, days=args.days)
    if args.json:
        print_rows(due_row(item, today) for item in items)
        return 0
    for item in items:
        when = "never calibrated here" if item.due is None else f"due {item.due}"
        overdue = " (OVERDUE)" if item.due is not None and item.due < today else ""
        print(f"{item.kind:9s} {item.identifier}\t{item.owner}\t{when}{overdue}")
    print(f"{len(items)} due within {args.days} days")
    return 0


def cmd_history(args: argparse.Namespace) -> int:
    history = _lab(args).history(args.serial)
    if args.plot is not None and not history.points:
        raise RecordsUsageError(f"--plot: no calibrations of {args.serial} on record to plot")
    if args.json and args.plot is None:
        print(json.dumps(history_object(history), indent=2, ensure_ascii=False))
        return 0
    if args.json:
        raise RecordsUsageError("--json: prints the history alone; --plot writes a chart (one)")
    for p in history.points:
        u = (
            "n/a"
            if p.expanded_uncertainty_mv_per_ms2 is None
            else f"{p.expanded_uncertainty_mv_per_ms2:.3g}"
        )
        shared = (
            f"; in batch {p.batch_id} with {', '.join(p.shared_with) or 'no other DUT on record'}"
            if p.batch_id
            else ""
        )
        print(
            f"{p.started_utc:%Y-%m-%d}  {p.run_id}  {p.sensitivity_mv_per_ms2:.5g} "
            f"mV/(m/s^2) at {p.reference_frequency_hz:g} Hz, U = {u}{shared}"
        )
    if history.drift_percent_per_year is None:
        print("drift: needs two calibrations at least 30 days apart")
    else:
        print(f"drift: {history.drift_percent_per_year:+.3f} % per year")
    if args.plot is not None:
        from app.files import check_target
        from app.records.db.plots import drift_chart

        try:
            check_target(args.plot)
        except (ValueError, FileExistsError) as exc:
            raise RecordsUsageError(f"--plot: {exc}") from None

        drift_chart(history, args.plot)
        print(f"chart written to {args.plot}")
    return 0


def cmd_register(args: argparse.Namespace) -> int:
    if args.action == "issue":
        raise RecordsUsageError(
            "register issue: removed (it gave a number without its certificate); issue with "
            "`accelcal certificate RUN_FOLDER` (number, PDF, DCC and register entry in one "
            "step; --replaces/--reason amend, --as-found names the run before adjustment)"
        )
    lab = _lab(args)
    if args.action in REVIEW_ACTIONS:
        return REVIEW_ACTIONS[args.action](lab, args)
    if args.action == "withdraw":
        lab.withdraw_certificate(args.number, args.reason)
        print(f"{args.number} withdrawn")
        return 0
    if args.action == "set":
        lab.set_setting(args.key, args.value)
        print(f"{args.key} = {args.value}")
        return 0
    under_review = {r.number: r.subject for r in lab.reviews(open_only=True)}
    register = lab.register()
    if args.json:
        print_rows(certificate_row(c, under_review) for c in register)
        return 0
    for c in register:
        note = f" replaces {c.replaces}" if c.replaces else ""
        if c.number in under_review:
            note += f" UNDER REVIEW ({under_review[c.number]})"
        if c.as_found_run is not None:
            note += f" (as found: run {c.as_found_run.run_id})"
        why = f" ({c.reason})" if c.reason else ""
        print(
            f"{c.number}\t{c.state}{why}\t{c.issued_utc:%Y-%m-%d}\trun {c.run.run_id}\t"
            f"sensor {c.sensor.serial}\tprepared {c.prepared_by}, approved {c.approved_by}{note}"
        )
    return 0


def cmd_control(args: argparse.Namespace) -> int:
    charts = _lab(args).control_chart(args.serial)
    if args.json:
        print_rows(control_row(chart) for chart in charts)
        return 0
    if not charts:
        print(f"{args.serial}: no complete runs on record")
    for chart in charts:
        print(f"{chart.stand}: {len(chart.points)} runs")
        if chart.centre is None:
            print("  limits: need 5 earlier runs on this stand")
        else:
            print(
                f"  centre {chart.centre:.5g}, limits {chart.lower:.5g} to {chart.upper:.5g} "
                "mV/(m/s^2)"
            )
        for run_id, value in chart.points:
            print(f"  {run_id}  {value:.5g}")
        if chart.warning:
            print(f"WARNING {chart.warning}")
    return 0
