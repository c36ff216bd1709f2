"""The `accelcal` argument parser: every command's options, their bounds and help (the
commands themselves live in one module each)."""

from __future__ import annotations

import argparse
from datetime import date
from pathlib import Path
from typing import Any

from app.cli.options import (
    COVERAGE,
    GAIN,
    LEVEL,
    RANGE,
    SEED,
    SEGMENTS,
    SENSITIVITY,
    SETTLE_PERIODS,
    SIM_PERIODS,
    SIM_SETTLE,
    SKEW,
    TEMPERATURE,
    TOLERANCE,
    Bounded,
    QuantityType,
    dut_entry,
    dut_name,
    numeric_option,
)
from app.cli.plan_parser import add_plan_command, add_plan_options
from app.cli.records import Handler
from app.cli.records import add_commands as add_records_commands
from app.cli.toplevel import top_parser
from app.io.quantities import PERCENT_RULE
from app.procedure.modes import MODE_MULTISINE
from app.procedure.options import (
    EXACT_MAINS_HELP,
    RESONANCE_HELP,
    OptionSpec,
    option,
)
from app.stand.simulated import FAULT_KINDS
from dsp.estimators import ESTIMATORS
from dsp.profiles import Profile

WORKERS = Bounded(int, 1, 64)
PERCENT_HELP = PERCENT_RULE.replace("%", "%%")  # argparse %-formats help texts
RECORDS_COMMANDS: dict[str, Handler] = {}  # filled by build_parser (app.cli.records)

MCM_TRIALS = Bounded(int, 1000, 10_000_000, unit="trials")  # JCGM 101 7.2: 10^6 for 95 %


def _iso_day(text: str) -> date:
    try:
        return date.fromisoformat(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a date yyyy-mm-dd: {text!r}") from None


SPEC_KINDS = ("datasheet", "customer", "standard")  # app.certificate.info.SpecKind


def humidity(text: str) -> float:
    """--humidity: '45%' or '45' as % relative humidity (app.stand.instruments)."""
    from app.stand.instruments import parse_humidity

    try:
        value = parse_humidity(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    if value is None:
        raise argparse.ArgumentTypeError("humidity (--humidity): empty")
    return value


SIM_HUM_HELP = (
    "simulated: hum only while driven (a power-amplifier ground loop), e.g. 1mV@50.3Hz on the "
    "DUT channel or 1mV/0.2mV@100Hz (DUT/reference, V peak); repeatable"
)


def _run_option(
    p: argparse.ArgumentParser | argparse._ArgumentGroup, name: str, **kwargs: Any
) -> None:
    """Add the run option `name` as app.procedure.options.RUN_OPTIONS states it: its flag, its
    parser (a quantity with its unit by `QuantityType`, a number within its bounds by
    `Bounded`, else the table's own), choices and help."""
    spec = option(name)
    help_text = spec.help.replace("%", "%%")  # argparse %-formats help texts
    if spec.metavar:
        kwargs.setdefault("metavar", spec.metavar)
    if "type" in kwargs:
        pass
    elif spec.quantity is not None:  # with its unit (0.5g, 100mV/g, 2min, 0.2%)
        numeric_option(p, spec.flag, QuantityType(spec.quantity, per=spec.per), help_text, **kwargs)
        return
    elif spec.parse is not None:
        kwargs["type"] = _table_parser(spec)
    elif spec.choices:
        kwargs["choices"] = spec.choices
    elif spec.bounds is not None:
        b = spec.bounds
        kind = int if b.whole else float
        bounded = Bounded(
            kind, b.low, b.high, open_low=b.open_low, open_high=b.open_high, unit=spec.unit
        )
        numeric_option(p, spec.flag, bounded, help_text, **kwargs)
        return
    p.add_argument(spec.flag, help=help_text, **kwargs)


def _table_parser(spec: OptionSpec) -> Any:
    """An argparse type of the table's parser: its ValueError becomes argparse's message."""

    def parse(text: str) -> Any:
        try:
            return spec.parse(text) if spec.parse is not None else text
        except ValueError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None

    parse.__name__ = spec.name
    return parse


def _add_run_options(r: argparse.ArgumentParser) -> None:
    """`accelcal run`'s options: the run's own from the options table, then the face's."""
    r.add_argument("--sim", action="store_true", help="the built-in simulated stand (default)")
    r.add_argument("--stand", type=Path, help="stand configuration (stand.toml)")
    _run_option(r, "dut", type=dut_entry, action="append", metavar="MODEL|POSITION=SERIAL")
    r.add_argument(
        "--dut-model",
        action="append",
        default=[],
        metavar="POSITION=MODEL",
        help="several DUTs in one run (issue 36): --dut POSITION=SERIAL once per DUT names "
        "the stand file's [[fixture.position]] and the DUT's serial; on the simulated stand "
        "the catalogue model at a position (default: the bare --dut MODEL, else piezo)",
    )
    r.add_argument(
        "--orientation",
        choices=("x", "y", "z"),
        help="a triaxial DUT (issue 36): --dut POSITION=SERIAL names a position with axes; "
        "this run has the sensor's axis x, y or z along the exciter (one run per orientation)",
    )
    _run_option(r, "dut_id", default=None)
    _run_option(r, "technician")
    _run_option(r, "nominal_mv_per_ms2")
    _run_option(r, "preset")
    _run_option(r, "level_ms2")
    r.add_argument(
        "--levels",
        help=f"amplitude sweep: levels, e.g. 4,5,6,7,8 (m/s^2) or 0.4g,0.5g; {LEVEL.describe()}",
    )
    _run_option(r, "periods")
    g = r.add_argument_group("range (issue 26): lines, rate, period, profile, exciter")
    for name in ("frequencies_hz", "sample_rate_hz", "period_samples", "reference_frequency_hz"):
        _run_option(g, name)
    _run_option(g, "profile", default=Profile.ACCELERATION.value)
    for name in ("corner_hz", "exciter", "fade_in_s"):
        _run_option(g, name)
    r.add_argument(
        "--resonance",
        action="store_true",
        help=RESONANCE_HELP,
    )
    _run_option(r, "target_type_a")
    _run_option(r, "max_acquisition_s")
    _run_option(r, "estimator")  # None: the mode's default (RunOptions.from_values)
    _run_option(r, "mode", default=MODE_MULTISINE)
    _run_option(r, "stepped_block_s")
    _run_option(r, "tolerance_percent")
    _run_option(r, "dut_mass_g")
    r.add_argument(
        "--fresh-response",
        action="store_true",
        help="identify the stand's response anew instead of starting from the stored one",
    )
    _run_option(r, "seed", default=0)
    r.add_argument("--paced", action="store_true", help="simulated stand: real time")
    r.add_argument(
        "--fault",
        action="append",
        default=[],
        help=f"simulated: KIND@SECONDS, KIND one of {', '.join(FAULT_KINDS)}",
    )
    r.add_argument(
        "--sim-hum",
        action="append",
        default=[],
        metavar="AMPLITUDE@FREQUENCY",
        help=SIM_HUM_HELP,
    )
    r.add_argument("--exact-mains-bins", action="store_true", help=EXACT_MAINS_HELP)
    r.add_argument("--out", type=Path, default=Path("runs"), help="folder for run folders")
    r.add_argument("--json", action="store_true", help="the run record as JSON")
    r.add_argument(
        "--fail-exit",
        action="store_true",
        help="exit with status 4 when the run completes with the verdict FAIL (without it a "
        "completed run exits 0 whatever its verdict; 2 refused, 3 aborted)",
    )
    records = r.add_argument_group("records (accelcal db)")
    records.add_argument(
        "--sensor",
        metavar="SERIAL",
        help="the DUT from the records: its serial, nominal, tolerance, level and plan",
    )
    records.add_argument(
        "--db", metavar="URL", help="records database (default $ACCELCAL_DB, else SQLite file)"
    )
    records.add_argument(
        "--teds",
        action="store_true",
        help="identify the DUT by its TEDS (the records' sensor with that identity, else the "
        "TEDS serial and nominal sensitivity)",
    )
    _run_option(records, "reference_override")


def build_parser() -> argparse.ArgumentParser:
    parser, sub = top_parser()

    add_plan_command(sub)

    a = sub.add_parser("analyze", help="re-analyse a recording (HDF5 of this program, CSV or TDMS)")
    a.add_argument(
        "file", type=Path, help="recording.h5, recording.csv, recording.tdms or a run folder"
    )
    a.add_argument(
        "--estimator",
        choices=ESTIMATORS,
        default=None,
        help="line estimator (default: the one the run folder's settings name; periodic for a "
        "recording that names none, or with --segments)",
    )
    numeric_option(a, "--segments", SEGMENTS, "the seed's protocol: L equal segments")
    numeric_option(a, "--coverage", COVERAGE, "coverage probability", default=0.9545)
    a.add_argument(
        "--seed-rule",
        action="store_true",
        help="the seed's coverage factor rule k = t(L-1), kept to reproduce the paper; not GUM "
        "(it ignores the type B degrees of freedom): the results are for review only",
    )
    numeric_option(
        a,
        "--mcm",
        MCM_TRIALS,
        "validate each line's GUM interval by JCGM 101 Monte Carlo (alone: 10^6 trials); "
        "stored per line, the Monte Carlo interval stated where clause 8 fails",
        nargs="?",
        const=1_000_000,
        default=None,
    )
    numeric_option(
        a, "--tolerance", TOLERANCE, f"DUT tolerance of the characteristic, {PERCENT_HELP}"
    )
    a.add_argument("--json", action="store_true", help="results as JSON")
    a.add_argument("--csv", type=Path, help="also write the per-line results as CSV here")
    a.add_argument("--overwrite", action="store_true", help="--csv may replace an existing file")
    csv_group = a.add_argument_group(
        "CSV and TDMS recordings (an HDF5 recording carries these; on one, "
        "--reference-frequency, --settle-periods and --mains re-analyse it, the others are "
        "refused; a TDMS file gives the sample rate, 1/wf_increment)"
    )
    add_plan_options(csv_group)
    numeric_option(
        csv_group, "--reference-sensitivity", SENSITIVITY, "e.g. 1.02 (mV/(m/s^2)) or 10mV/g"
    )
    numeric_option(csv_group, "--reference-gain", GAIN, "V/V", default=None)
    numeric_option(csv_group, "--dut-gain", GAIN, "V/V", default=None)
    numeric_option(
        csv_group,
        "--skew",
        SKEW,
        "inter-channel delay in s, positive when the DUT channel is sampled after the "
        "reference (e.g. 2e-06 or -2e-06); or a '# skew_s = ...' line in the CSV, the "
        "property accelcal_skew_s in the TDMS (DUT channel, its group or the file). Without "
        "either the phase is not corrected for skew and not stated",
        default=None,
        metavar="SECONDS",
    )
    numeric_option(
        csv_group,
        "--settle-periods",
        SETTLE_PERIODS,
        "leading periods to skip (CSV, TDMS: of the file, default 0; HDF5: of the analysed ones)",
        default=None,
    )
    numeric_option(csv_group, "--range", RANGE, "channel range, V", dest="range_v")
    csv_group.add_argument("--budget", type=Path, help="type B budget, TOML [[component]]")
    tdms_group = a.add_argument_group("TDMS recordings (channels in volts)")
    tdms_group.add_argument(
        "--reference", metavar="CHANNEL", help="reference channel: group/channel or its name"
    )
    tdms_group.add_argument(
        "--dut", metavar="CHANNEL", help="DUT channel: group/channel or its name"
    )

    r = sub.add_parser("run", help="run a calibration (simulated stand unless --stand)")
    _add_run_options(r)

    w = sub.add_parser("show", help="print a stored run, or a batch's members")
    w.add_argument(
        "run", type=Path, help="run folder, or a batch folder (several DUTs in one run) or its id"
    )
    w.add_argument("--json", action="store_true", help="the run record as JSON")

    sub.add_parser("devices", help="NI-DAQmx devices and VISA resources found, or why none")

    g = sub.add_parser("gui", help="the technician's window")
    g.add_argument("--sim", action="store_true", help="the built-in simulated stand (default)")
    g.add_argument("--stand", type=Path, help="stand configuration (stand.toml)")
    g.add_argument("--dut", type=dut_name, help="simulated DUT to preselect")
    g.add_argument("--unpaced", action="store_true", help="simulated stand faster than real time")
    numeric_option(g, "--seed", SEED, "simulated stand: random seed", default=0)
    g.add_argument("--out", type=Path, default=Path("runs"), help="folder for run folders")
    g.add_argument(
        "--sim-hum",
        action="append",
        default=[],
        metavar="AMPLITUDE@FREQUENCY",
        help=SIM_HUM_HELP,
    )
    g.add_argument("--autorun", action="store_true", help="start a run at once")
    g.add_argument("--screenshot", type=Path, help="save a PNG of the window (after the run)")
    g.add_argument("--quit-after-run", action="store_true", help="close when the run ends")
    g.add_argument("--db", help="records database URL (default: $ACCELCAL_DB, else the local file)")

    c = sub.add_parser("certificate", help="the PDF certificate of a stored complete run")
    c.add_argument("run", type=Path, nargs="?", help="run folder")
    c.add_argument(
        "--batch",
        metavar="BATCH",
        help="several DUTs in one run: one certificate per member of the batch (its folder, or "
        "its id under the runs folder ./runs), each its own number",
    )
    c.add_argument(
        "--triaxial",
        nargs=3,
        metavar="BATCH",
        help="a triaxial sensor (issue 36): its three orientation runs' batches (folders, or "
        "ids under ./runs; x, y, z in any order) make one certificate with the three axes, "
        "the sensitivity matrix and the transverse sensitivities",
    )
    c.add_argument(
        "--out",
        type=Path,
        help="PDF to write (default: <run>/certificate.pdf; an amendment: the next free "
        "<run>/certificate-N.pdf)",
    )
    c.add_argument("--customer", help="customer name (mandatory)")
    c.add_argument(
        "--customer-address", default="", help="customer address (required, or the next)"
    )
    c.add_argument(
        "--address-not-stated",
        default="",
        metavar="REASON",
        help="why the customer's address is not given (recorded and printed)",
    )
    c.add_argument(
        "--authorised-by",
        help="who authorises it (mandatory): the name alone; under the records' two-person "
        "rule a user of the records (user name or recorded name)",
    )
    c.add_argument(
        "--authorised-function",
        default="",
        help="the signatory's function, printed under the name (e.g. 'head of laboratory')",
    )
    c.add_argument("--dut-model", help="DUT manufacturer and model")
    c.add_argument("--dut-serial", help="DUT serial number (default: the run's --dut-id)")
    c.add_argument("--dut-type", help="DUT type, e.g. 'piezoelectric accelerometer'")
    numeric_option(c, "--temperature", TEMPERATURE, "ambient temperature, deg C")
    c.add_argument(
        "--humidity", type=humidity, help="relative humidity, e.g. 45%% (default: the run's sensor)"
    )
    c.add_argument(
        "--mounting", help="how the DUT was mounted (default: the last for its model or template)"
    )
    c.add_argument(
        "--spec-kind",
        choices=SPEC_KINDS,
        help="the conformity statement's specification: manufacturer's data sheet, customer "
        "requirement or standard",
    )
    c.add_argument("--spec-id", help="its document and revision, e.g. 'PCB 352C33 rev. D'")
    c.add_argument("--spec-tolerances", help="its tolerances (default: those the verdict checked)")
    c.add_argument("--certificate-number", help="without records; default: AC-<run id>")
    c.add_argument(
        "--issue-date", help="YYYY-MM-DD, UTC (default: today; not before the calibration)"
    )
    c.add_argument("--notes", default="", help="free text printed under Notes")
    c.add_argument("--sweep", type=Path, help="sweep summary (sweep-*.json) the run belongs to")
    c.add_argument(
        "--sign",
        type=Path,
        metavar="P12",
        help="sign the PDF (PAdES) with the lab's key; password from $ACCELCAL_SIGN_PASSWORD",
    )
    c.add_argument(
        "--trust",
        type=Path,
        metavar="CA",
        help="the lab's CA certificate (PEM or DER): a validation report signed under it is "
        "named (default: the --sign key's own certificates)",
    )
    cr = c.add_argument_group("records (accelcal db): customer, sensor and number from there")
    cr.add_argument(
        "--db",
        metavar="URL",
        help="records database (default $ACCELCAL_DB, else the SQLite file when it exists)",
    )
    cr.add_argument(
        "--prepared-by",
        help="who prepared it (default: the technician the run records, run --technician)",
    )
    cr.add_argument("--replaces", metavar="NUMBER", help="the certificate this one amends")
    cr.add_argument("--reason", help="why it amends the one it replaces")
    cr.add_argument("--as-found", metavar="RUN_ID", help="the run before adjustment (as found)")

    s = sub.add_parser("simulate", help="record a calibration on the simulated stand")
    s.add_argument("--list", action="store_true", help="print the simulated catalogue")
    s.add_argument("--dut", type=dut_name, default="piezo", help="catalogue DUT (see --list)")
    numeric_option(s, "--level", LEVEL, "peak acceleration per line, e.g. 5 or 0.5g", default=5.0)
    numeric_option(s, "--periods", SIM_PERIODS, "periods to record after settling", default=8)
    numeric_option(s, "--settle", SIM_SETTLE, "settling periods after the fade-in", default=2)
    numeric_option(s, "--seed", SEED, "random seed (noise, stand deviations)", default=0)
    s.add_argument(
        "--fault",
        action="append",
        default=[],
        help=f"inject KIND@SECONDS, KIND one of {', '.join(FAULT_KINDS)}",
    )
    s.add_argument("--out", type=Path, help="recording to write (.h5)")
    s.add_argument("--overwrite", action="store_true", help="--out may replace an existing file")
    s.add_argument("--json", action="store_true", help="machine-readable output")
    t = sub.add_parser("teds", help="a sensor's TEDS (IEEE 1451.4): decode a file, read, write")
    tsub = t.add_subparsers(dest="teds_command", required=True, metavar="ACTION")
    tsub.add_parser("decode", help="decode an NI .ted file").add_argument("file", type=Path)
    tr = tsub.add_parser("read", help="read the DUT channel's TEDS on a stand")
    tw = tsub.add_parser("write", help="write a complete run's sensitivity and date to the TEDS")
    tw.add_argument("run", type=Path, help="the run folder whose result is written")
    tw.add_argument("--initials", default="", help="calibrator's initials, up to 3 letters")
    tw.add_argument("--yes", action="store_true", help="write without asking (scripts)")
    tw.add_argument(
        "--yes-different-sensor",
        metavar="REASON",
        help="write although the TEDS names another sensor than the run's (logged, audited)",
    )
    tw.add_argument("--db", metavar="URL", help="records database (the run's sensor identity)")
    for p in (tr, tw):
        p.add_argument("--stand", type=Path, help="stand configuration (default: simulated)")
        p.add_argument("--dut", type=dut_name, default="piezo", help="simulated DUT")
        numeric_option(p, "--seed", SEED, "simulated stand: random seed", default=0)
        p.add_argument(
            "--channel",
            metavar="CHANNEL",
            help="one DUT input of the stand file's fixture, e.g. dut.B (default: the DUT channel)",
        )

    v = sub.add_parser("verify", help="check a certificate PDF (or its DCC): signatures, DCC, run")
    v.add_argument("pdf", type=Path, help="certificate PDF, or its DCC (.xml) alone")
    v.add_argument("--run", type=Path, help="the run folder it certifies (manifest and numbers)")
    v.add_argument("--trust", type=Path, help="the CA certificate (PEM or DER) to trust")
    v.add_argument("--validation-report", type=Path, help="the validation report PDF it names")
    v.add_argument(
        "--triaxial",
        nargs=3,
        metavar="BATCH",
        help="a triaxial certificate: its three orientation batches, the section recomputed "
        "from their nine runs and compared with the DCC value by value",
    )
    v.add_argument(
        "--db",
        metavar="URL",
        help="records database whose register says whether it is in force (default "
        "$ACCELCAL_DB, else the default records file when it exists)",
    )
    im = sub.add_parser("impact", help="impact of a corrected reference standard (17025 7.10)")
    im.add_argument("serial", help="the reference standard's serial or id")
    im.add_argument("--table", type=Path, required=True, help="corrected table CSV (refs layout)")
    im.add_argument(
        "--since", type=_iso_day, help="window start yyyy-mm-dd (default: its calibration)"
    )
    im.add_argument("--until", type=_iso_day, help="window end yyyy-mm-dd (default: now)")
    im.add_argument("--out", type=Path, help="report folder (default ./impact-SERIAL-TIME)")
    numeric_option(im, "--workers", WORKERS, "worker processes (default: one per core)")
    im.add_argument("--no-flag", action="store_true", help="report only: flag no certificate")
    im.add_argument("--db", metavar="URL", help="records database (default $ACCELCAL_DB)")
    va = sub.add_parser("validate", help="the 17025 7.11.2 software validation report")
    va.add_argument("--out", type=Path, help="the report PDF (default: the lab validation folder)")
    va.add_argument(
        "--sign",
        type=Path,
        metavar="P12",
        help="sign the report with the lab's key (password from $ACCELCAL_SIGN_PASSWORD); "
        "a certificate names only a signed report",
    )
    from app.cli.web import add_web_commands

    add_web_commands(sub)
    RECORDS_COMMANDS.update(add_records_commands(sub))
    return parser
