"""The `accelcal` command line: thin, it calls the same code as the GUI and prints results.

Exit codes: 0 success, 2 bad input (options, plan, file), 1 any other failure.
"""

from __future__ import annotations

import argparse
import csv
import difflib
import io
import json
import math
import os
import re
import sys
import tempfile
import tomllib
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

# Only light modules at the top (numpy at most): `accelcal --help` and the parser stay quick
# (bench/startup.py, tests/app/test_startup.py). Every command imports what it uses.
from app import formatting as fmt
from app import lines
from app.cli.options import Bounded
from app.cli.options import numeric_option as _numeric
from app.files import FileExistsRefusal, check_target, write_new
from app.io.checks import MAX_TEXT_BYTES, InputFileError, check_input_file
from app.io.vocabulary import RunStatus
from app.procedure.modes import MODE_MULTISINE, MODES
from app.records.db.cli import Handler
from app.records.db.cli import add_commands as add_records_commands
from app.records.db.errors import RecordsInputError
from dsp.estimators import DEFAULT_ESTIMATOR, ESTIMATORS
from dsp.multisine import PRESETS, Plan, PlanError, make_plan
from hardware.errors import HardwareError
from sim.faults import FAULT_KINDS
from sim.models import DUT_CATALOGUE, StandModel

if TYPE_CHECKING:
    from app.procedure.run import RunRequest
    from dsp.calibration import ReferenceChain, Results
    from dsp.uncertainty import Budget
    from sim.stand import Fault

EXIT_OK, EXIT_FAILURE, EXIT_BAD_INPUT, EXIT_ABORTED = 0, 1, 2, 3
EXIT_BROKEN_PIPE = 128 + 13  # SIGPIPE: the reader of stdout went away (`| head`)
RECORDS_COMMANDS: dict[str, Handler] = {}  # filled by build_parser (app.records.db.cli)


class UsageError(ValueError):
    """Bad command-line input; the message names the option."""


def parse_frequencies(text: str) -> list[float]:
    """--frequencies: a line list (see app.lines.parse_frequencies)."""
    try:
        return lines.parse_frequencies(text)
    except ValueError as exc:
        raise UsageError(f"--frequencies: {exc}") from None


def _positive(name: str, value: float | None) -> None:
    if value is not None and not (math.isfinite(value) and value > 0):
        raise UsageError(f"{name}: must be > 0, got {value:g}")


def _plan_from_options(args: argparse.Namespace, *, optimise: bool) -> Plan:
    """The plan the options describe: a preset, with any of its fields overridden."""
    preset = PRESETS[args.preset or "piezo"]
    freqs = (
        parse_frequencies(args.frequencies)
        if args.frequencies is not None
        else list(preset.nominal_frequencies_hz)
    )
    for name in ("sample_rate", "level", "reference_frequency", "mains"):
        _positive("--" + name.replace("_", "-"), getattr(args, name))
    if args.period is not None and args.period < 4:
        raise UsageError(f"--period: must be >= 4 samples, got {args.period}")
    return make_plan(
        freqs,
        args.sample_rate or preset.sample_rate_hz,
        args.period or preset.period_samples,
        args.level or preset.level_ms2,
        args.reference_frequency or preset.reference_frequency_hz,
        mains_frequency_hz=args.mains if args.mains is not None else 50.0,
        shift_mains_lines=getattr(args, "shift_mains", False),
        phases_rad=None if optimise else [0.0] * len(freqs),
    )


# The bounds of every numeric option (also in docs/reliability.md).
SAMPLE_RATE = Bounded(float, 1.0, 1e7, unit="Hz")
PERIOD = Bounded(int, 4, 2**22, unit="samples")
LEVEL = Bounded(float, 0.0, 1000.0, open_low=True, unit="m/s^2")
FREQUENCY = Bounded(float, 0.0, 1e6, open_low=True, unit="Hz")
MAINS = Bounded(float, 1.0, 1000.0, unit="Hz")
SEGMENTS = Bounded(int, 1, 10_000)
COVERAGE = Bounded(float, 0.0, 1.0, open_low=True, open_high=True)
TOLERANCE = Bounded(float, 0.0, 100.0, open_low=True, unit="%")
SENSITIVITY = Bounded(float, 0.0, 1e6, open_low=True, unit="mV/(m/s^2)")
DUT_MASS = Bounded(float, 0.0, 100_000.0, unit="g")
GAIN = Bounded(float, 0.0, 1e6, open_low=True, unit="V/V")
SKEW = Bounded(float, -1e-3, 1e-3, unit="s")
SETTLE_PERIODS = Bounded(int, 0, 10_000)
RANGE = Bounded(float, 0.0, 1000.0, open_low=True, unit="V")
RUN_PERIODS = Bounded(int, 2, 10_000)
SIM_PERIODS = Bounded(int, 1, 10_000)
SIM_SETTLE = Bounded(int, 0, 1000)
SEED = Bounded(int, 0, 2**32 - 1)
TEMPERATURE = Bounded(float, -50.0, 150.0, unit="deg C")
TARGET_UA = (0.0, 1.0)  # --target-ua: (0, 100 %]
MAX_TIME_S = 24 * 3600.0  # --max-time: (0, 24 h]


def _dut_name(text: str) -> str:
    """--dut: a DUT of the simulated stand's catalogue (argparse type)."""
    if text in DUT_CATALOGUE:
        return text
    close = difflib.get_close_matches(text, list(DUT_CATALOGUE), n=1)
    hint = f"; did you mean {close[0]!r}?" if close else ""
    raise argparse.ArgumentTypeError(
        f"{text!r} is not in the DUT catalogue ({', '.join(DUT_CATALOGUE)}){hint}"
    )


class _Parser(argparse.ArgumentParser):
    """ArgumentParser that takes an argument starting with a minus and a digit as a value, never
    an option: a negative number in any float notation (-2e-06, -.5, -1.5E3) or a list that
    starts with one (-10,160); argparse's own rule misses the exponent form and lists. No
    option of this program starts with a digit."""

    def __init__(self, *args: object, **kwargs: object) -> None:
        super().__init__(*args, **kwargs)  # type: ignore[arg-type]
        self._negative_number_matcher = NEGATIVE_NUMBER


NEGATIVE_NUMBER = re.compile(r"^-\.?\d")


class _Version(argparse.Action):
    """--version: the version (which asks git) is looked up only when asked for, not at every
    start-up."""

    def __init__(self, option_strings: list[str], dest: str, **kwargs: object) -> None:
        kwargs.pop("default", None)
        super().__init__(option_strings, dest, nargs=0, default=argparse.SUPPRESS, **kwargs)  # type: ignore[arg-type]

    def __call__(self, parser, namespace, values, option_string=None) -> None:  # type: ignore[no-untyped-def]
        from app.version import software_version

        parser._print_message(f"accelcal {software_version()}\n", sys.stdout)
        parser.exit()


def _add_plan_options(p: argparse.ArgumentParser | argparse._ArgumentGroup) -> None:
    p.add_argument("--preset", choices=sorted(PRESETS), help="named plan (default piezo)")
    p.add_argument("--frequencies", help="line list in Hz, e.g. 10,12.5,...,2500 (ISO 266 fill)")
    _numeric(p, "--sample-rate", SAMPLE_RATE, "sample rate in Hz")
    _numeric(p, "--period", PERIOD, "period length in samples")
    _numeric(p, "--level", LEVEL, "target peak acceleration per line, m/s^2")
    _numeric(p, "--reference-frequency", FREQUENCY, "reference frequency in Hz")
    _numeric(p, "--mains", MAINS, "mains frequency in Hz (50)", default=None)


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="accelcal",
        description="Accelerometer calibration by comparison, multisine excitation.",
    )
    parser.add_argument("--version", action=_Version, help="show the version and exit")
    parser.add_argument(
        "--verbose",
        action="store_true",
        help="also show what a run writes to its run.log, and information messages, on stderr",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("plan", help="show a frequency plan, its checks and predicted peaks")
    _add_plan_options(p)
    p.add_argument("--shift-mains", action="store_true", help="move lines off mains harmonics")
    p.add_argument("--json", action="store_true", help="machine-readable output")

    a = sub.add_parser("analyze", help="re-analyse a recording (HDF5 of this program, CSV or TDMS)")
    a.add_argument(
        "file", type=Path, help="recording.h5, recording.csv, recording.tdms or a run folder"
    )
    a.add_argument("--estimator", choices=ESTIMATORS, default=DEFAULT_ESTIMATOR)
    _numeric(a, "--segments", SEGMENTS, "the seed's protocol: L equal segments")
    _numeric(a, "--coverage", COVERAGE, "coverage probability", default=0.9545)
    a.add_argument("--seed-rule", action="store_true", help="the seed's coverage factor rule")
    _numeric(a, "--tolerance", TOLERANCE, "DUT tolerance of the characteristic, %%")
    a.add_argument("--json", action="store_true", help="results as JSON")
    a.add_argument("--csv", type=Path, help="also write the per-line results as CSV here")
    a.add_argument("--overwrite", action="store_true", help="--csv may replace an existing file")
    csv_group = a.add_argument_group(
        "CSV and TDMS recordings (an HDF5 recording carries these; on one, "
        "--reference-frequency, --settle-periods and --mains re-analyse it, the others are "
        "refused; a TDMS file gives the sample rate, 1/wf_increment)"
    )
    _add_plan_options(csv_group)
    _numeric(csv_group, "--reference-sensitivity", SENSITIVITY, "mV/(m/s^2)")
    _numeric(csv_group, "--reference-gain", GAIN, "V/V", default=None)
    _numeric(csv_group, "--dut-gain", GAIN, "V/V", default=None)
    _numeric(
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
    _numeric(
        csv_group,
        "--settle-periods",
        SETTLE_PERIODS,
        "leading periods to skip (CSV, TDMS: of the file, default 0; HDF5: of the analysed ones)",
        default=None,
    )
    _numeric(csv_group, "--range", RANGE, "channel range, V", dest="range_v")
    csv_group.add_argument("--budget", type=Path, help="type B budget, TOML [[component]]")
    tdms_group = a.add_argument_group("TDMS recordings (channels in volts)")
    tdms_group.add_argument(
        "--reference", metavar="CHANNEL", help="reference channel: group/channel or its name"
    )
    tdms_group.add_argument(
        "--dut", metavar="CHANNEL", help="DUT channel: group/channel or its name"
    )

    r = sub.add_parser("run", help="run a calibration (simulated stand unless --stand)")
    r.add_argument("--sim", action="store_true", help="the built-in simulated stand (default)")
    r.add_argument("--stand", type=Path, help="stand configuration (stand.toml)")
    r.add_argument(
        "--dut", type=_dut_name, default="piezo", help="simulated DUT from the catalogue"
    )
    r.add_argument("--dut-id", default=None, help="serial number / identification of the DUT")
    _numeric(r, "--nominal-sensitivity", SENSITIVITY, "DUT nominal, mV/(m/s^2)")
    r.add_argument("--preset", choices=sorted(PRESETS), help="plan (default: by DUT kind)")
    _numeric(r, "--level", LEVEL, "peak acceleration per line, m/s^2 (default 5)")
    r.add_argument(
        "--levels", help=f"amplitude sweep: levels in m/s^2, e.g. 4,5,6,7,8; {LEVEL.describe()}"
    )
    _numeric(r, "--periods", RUN_PERIODS, "periods to acquire", default=8)
    r.add_argument("--target-ua", help="stop at this relative type A, e.g. 0.2%%; (0, 100 %%]")
    r.add_argument("--max-time", help="bound on the acquisition time, e.g. 30s; (0, 24 h]")
    r.add_argument("--estimator", choices=ESTIMATORS, default=DEFAULT_ESTIMATOR)
    r.add_argument("--mode", choices=MODES, default=MODE_MULTISINE)
    _numeric(r, "--tolerance", TOLERANCE, "DUT tolerance of the characteristic, %%")
    _numeric(
        r,
        "--dut-mass",
        DUT_MASS,
        "DUT mass in g: its class picks the stand's stored response (default: the simulated "
        "DUT's catalogue mass; on real hardware not stated)",
    )
    r.add_argument(
        "--fresh-response",
        action="store_true",
        help="identify the stand's response anew instead of starting from the stored one",
    )
    _numeric(r, "--seed", SEED, "simulated stand: random seed", default=0)
    r.add_argument("--paced", action="store_true", help="simulated stand: real time")
    r.add_argument(
        "--fault",
        action="append",
        default=[],
        help=f"simulated: KIND@SECONDS, KIND one of {', '.join(FAULT_KINDS)}",
    )
    r.add_argument("--out", type=Path, default=Path("runs"), help="folder for run folders")
    r.add_argument("--json", action="store_true", help="the run record as JSON")
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
    records.add_argument(
        "--reference-override",
        metavar="REASON",
        help="use a reference standard past its due date, for this stated reason",
    )

    w = sub.add_parser("show", help="print a stored run")
    w.add_argument("run", type=Path, help="run folder")
    w.add_argument("--json", action="store_true", help="the run record as JSON")

    sub.add_parser("devices", help="NI-DAQmx devices and VISA resources found, or why none")

    g = sub.add_parser("gui", help="the technician's window")
    g.add_argument("--sim", action="store_true", help="the built-in simulated stand (default)")
    g.add_argument("--stand", type=Path, help="stand configuration (stand.toml)")
    g.add_argument("--dut", type=_dut_name, help="simulated DUT to preselect")
    g.add_argument("--unpaced", action="store_true", help="simulated stand faster than real time")
    _numeric(g, "--seed", SEED, "simulated stand: random seed", default=0)
    g.add_argument("--out", type=Path, default=Path("runs"), help="folder for run folders")
    g.add_argument("--autorun", action="store_true", help="start a run at once")
    g.add_argument("--screenshot", type=Path, help="save a PNG of the window (after the run)")
    g.add_argument("--quit-after-run", action="store_true", help="close when the run ends")
    g.add_argument("--db", help="records database URL (default: $ACCELCAL_DB, else the local file)")

    c = sub.add_parser("certificate", help="the PDF certificate of a stored complete run")
    c.add_argument("run", type=Path, help="run folder")
    c.add_argument("--out", type=Path, help="PDF to write (default: <run>/certificate.pdf)")
    c.add_argument("--customer", help="customer name (mandatory)")
    c.add_argument("--customer-address", default="", help="customer address")
    c.add_argument("--authorised-by", help="name and function of the signatory (mandatory)")
    c.add_argument("--dut-model", help="DUT manufacturer and model")
    c.add_argument("--dut-serial", help="DUT serial number (default: the run's --dut-id)")
    c.add_argument("--dut-type", help="DUT type, e.g. 'piezoelectric accelerometer'")
    _numeric(c, "--temperature", TEMPERATURE, "ambient temperature, deg C")
    c.add_argument("--mounting", help="how the DUT was mounted")
    c.add_argument("--certificate-number", help="default: AC-<run id>")
    c.add_argument("--issue-date", help="YYYY-MM-DD (default: the run's date)")
    c.add_argument("--notes", default="", help="free text printed under Notes")
    c.add_argument("--sweep", type=Path, help="sweep summary (sweep-*.json) the run belongs to")
    c.add_argument(
        "--sign",
        type=Path,
        metavar="P12",
        help="sign the PDF (PAdES) with the lab's key; password from $ACCELCAL_SIGN_PASSWORD",
    )
    cr = c.add_argument_group("records (accelcal db): customer, sensor and number from there")
    cr.add_argument("--db", metavar="URL", help="records database (default $ACCELCAL_DB)")
    cr.add_argument("--prepared-by", help="who prepared it (default: the login name)")
    cr.add_argument("--replaces", metavar="NUMBER", help="the certificate this one amends")
    cr.add_argument("--reason", help="why it amends the one it replaces")

    s = sub.add_parser("simulate", help="record a calibration on the simulated stand")
    s.add_argument("--list", action="store_true", help="print the simulated catalogue")
    s.add_argument("--dut", type=_dut_name, default="piezo", help="catalogue DUT (see --list)")
    _numeric(s, "--level", LEVEL, "peak acceleration per line, m/s^2", default=5.0)
    _numeric(s, "--periods", SIM_PERIODS, "periods to record after settling", default=8)
    _numeric(s, "--settle", SIM_SETTLE, "settling periods after the fade-in", default=2)
    _numeric(s, "--seed", SEED, "random seed (noise, stand deviations)", default=0)
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
    for p in (tr, tw):
        p.add_argument("--stand", type=Path, help="stand configuration (default: simulated)")
        p.add_argument("--dut", type=_dut_name, default="piezo", help="simulated DUT")
        _numeric(p, "--seed", SEED, "simulated stand: random seed", default=0)

    v = sub.add_parser("verify", help="check a certificate PDF: signature, DCC, run")
    v.add_argument("pdf", type=Path, help="certificate PDF")
    v.add_argument("--run", type=Path, help="the run folder it certifies (manifest and numbers)")
    v.add_argument("--trust", type=Path, help="the CA certificate (PEM or DER) to trust")
    RECORDS_COMMANDS.update(add_records_commands(sub))
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run one command; its exit code (EXIT_*, or EXIT_BROKEN_PIPE when the reader of stdout
    went away, e.g. `accelcal plan | head`)."""
    try:
        code = _main(argv)
        sys.stdout.flush()  # a closed pipe shows here, not at interpreter exit
        return code
    except BrokenPipeError:
        _silence_stdout()
        return EXIT_BROKEN_PIPE


def _silence_stdout() -> None:
    """Point stdout at /dev/null so the interpreter's final flush raises nothing."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError):
        pass


def _main(argv: Sequence[str] | None) -> int:
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help (0) or an option refused by argparse (2, message said)
        return exc.code if isinstance(exc.code, int) else EXIT_BAD_INPUT
    from app.logs import setup, teardown

    handler = setup(args.verbose)
    try:
        return _run_command(args)
    finally:
        teardown(handler)


def _run_command(args: argparse.Namespace) -> int:
    """The command's exit code, its errors turned into one line and an exit code."""
    try:
        return (COMMANDS | RECORDS_COMMANDS)[args.command](args)
    except BrokenPipeError:
        raise
    # the lazily imported modules' error classes are looked up when an error is matched (the
    # command has imported them by then), so this tuple is built in the except clause
    except (UsageError, PlanError, RecordsInputError, *_loaded(_BAD_INPUT_ERRORS)) as exc:  # type: ignore[misc]
        print(f"accelcal {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except HardwareError as exc:
        print(f"accelcal {args.command}: {type(exc).__name__}: {exc}", file=sys.stderr)
        return EXIT_FAILURE
    except _loaded(_NOT_RECORDED_ERRORS) as exc:
        print(f"accelcal {args.command}: {exc}", file=sys.stderr)
        return EXIT_ABORTED
    except Exception as exc:
        from app.logs import keep_traceback

        kept = keep_traceback(args.command, exc)
        where = f" (traceback in {kept})" if kept is not None else ""
        print(
            f"accelcal {args.command}: failed: {type(exc).__name__}: {exc}{where}",
            file=sys.stderr,
        )
        return EXIT_FAILURE


# Errors of the heavy modules, by (module, class): a module never imported raised none, so
# main() catches them without importing it.
_BAD_INPUT_ERRORS = (
    ("app.io.hdf5", "RecordingError"),
    ("dsp.segments", "SegmentError"),
    ("dsp.calibration", "AnalysisError"),
    ("app.stand.simulate", "SimulationError"),
    ("app.stand.config", "ConfigError"),
    ("app.procedure", "PreflightError"),
    ("app.certificate", "CertificateError"),
)
_NOT_RECORDED_ERRORS = (("app.procedure", "RunNotRecordedError"),)


def _loaded(errors: tuple[tuple[str, str], ...]) -> tuple[type[BaseException], ...]:
    """The classes named in `errors` whose module has been imported."""
    return tuple(
        getattr(sys.modules[module], name) for module, name in errors if module in sys.modules
    )


def _writable_folder(folder: Path, option: str) -> None:
    """UsageError naming `option` unless files can be created in `folder` (made if missing):
    its nearest existing ancestor must be a folder in which a file can really be created (a
    probe, so that read-only file systems are caught even when running as root)."""
    probe = folder
    while not probe.exists():
        if probe.parent == probe:
            break
        probe = probe.parent
    if not probe.is_dir():
        raise UsageError(f"{option}: {folder}: cannot be created ({probe} is not a folder)")
    try:
        with tempfile.TemporaryFile(dir=probe):
            pass
    except OSError as exc:
        reason = exc.strerror or type(exc).__name__
        raise UsageError(f"{option}: {folder}: not writable ({reason})") from None


def plan_report(plan: Plan) -> dict:
    peaks = plan.predicted_peaks()
    data = plan.to_dict()
    data.update(
        period_s=plan.period_s,
        resolution_hz=plan.resolution_hz,
        crest_factor=plan.crest_factor(),
        continuous_crest_factor=plan.continuous_crest_factor(),
        peak_acceleration_ms2=peaks.acceleration_ms2,
        peak_velocity_m_per_s=peaks.velocity_m_per_s,
        peak_displacement_m=peaks.displacement_m,
        peak_to_peak_displacement_m=peaks.displacement_peak_to_peak_m,
    )
    return data


def cmd_plan(args: argparse.Namespace) -> int:
    plan = _plan_from_options(args, optimise=True)
    report = plan_report(plan)
    if args.json:
        print(json.dumps(report, indent=2))
        return EXIT_OK
    print(
        f"Plan: {len(plan.lines)} lines, fs {plan.sample_rate_hz:g} Hz, period "
        f"{plan.period_samples} samples ({plan.period_s:g} s, bins {plan.resolution_hz:g} Hz), "
        f"reference {plan.reference_frequency_hz:g} Hz"
    )
    rows = [
        [
            f"{ln.nominal_frequency_hz:g}",
            f"{ln.frequency_hz:g}",
            str(ln.bin),
            f"{ln.amplitude_ms2:g}",
            f"{ln.phase_rad:.3f}",
        ]
        for ln in plan.lines
    ]
    print(fmt.table(["nominal Hz", "actual Hz", "bin", "peak m/s^2", "phase rad"], rows))
    print(
        f"Crest factor (acceleration): {report['crest_factor']:.2f} on the samples, "
        f"{report['continuous_crest_factor']:.2f} between them"
    )
    print(
        f"Predicted peaks: acceleration {report['peak_acceleration_ms2']:.1f} m/s^2, velocity "
        f"{1e3 * report['peak_velocity_m_per_s']:.1f} mm/s, displacement "
        f"{1e3 * report['peak_displacement_m']:.3f} mm "
        f"({1e3 * report['peak_to_peak_displacement_m']:.3f} mm p-p)"
    )
    for warning in plan.warnings:
        print(f"warning: {warning}")
    return EXIT_OK


def _load(args: argparse.Namespace):
    from app.io.hdf5 import read_csv
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
        _positive("--reference-frequency", args.reference_frequency)
        _positive("--mains", args.mains)
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
    chain, budget = _chain_and_budget(args, "CSV")
    plan = _plan_from_options(args, optimise=False)
    return read_csv(
        args.file,
        plan,
        chain,
        budget,
        settle_periods=args.settle_periods or 0,
        range_v=args.range_v,
    )


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
    _positive("--sample-rate", args.sample_rate)
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
    chain, budget = _chain_and_budget(args, "TDMS")
    plan_args = argparse.Namespace(**{**vars(args), "sample_rate": rate or args.sample_rate})
    plan = _plan_from_options(plan_args, optimise=False)
    return read_tdms(
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


def _chain_and_budget(args: argparse.Namespace, kind: str) -> tuple[ReferenceChain, Budget]:
    """The reference chain and budget of a CSV or TDMS recording, from the options."""
    from dsp.calibration import ReferenceChain
    from dsp.uncertainty import Budget

    if args.reference_sensitivity is None:
        raise UsageError(f"--reference-sensitivity: a {kind} recording needs it (mV/(m/s^2))")
    for name in ("reference_sensitivity", "reference_gain", "dut_gain", "sample_rate", "range_v"):
        _positive("--" + name.replace("_", "-"), getattr(args, name))
    if args.settle_periods is not None and args.settle_periods < 0:
        raise UsageError(f"--settle-periods: must be >= 0, got {args.settle_periods}")
    chain = ReferenceChain.flat(
        args.reference_sensitivity,
        reference_gain=args.reference_gain or 1.0,
        dut_gain=args.dut_gain or 1.0,
        skew_s=args.skew,  # None: from the file (header line, property), else unknown
    )
    budget = _read_budget(args.budget) if args.budget else Budget(())
    return chain, budget


def _read_budget(path: Path) -> Budget:
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
        return Budget.from_list(entries)
    except ValueError as exc:
        raise UsageError(f"--budget: {path}: {exc}") from None


def cmd_analyze(args: argparse.Namespace) -> int:
    from app.procedure.analysis import analyze, status_warning

    if not 0 < args.coverage < 1:
        raise UsageError(f"--coverage: must be between 0 and 1, got {args.coverage:g}")
    if args.segments is not None and args.segments < 1:
        raise UsageError(f"--segments: must be >= 1, got {args.segments}")
    if args.csv is not None:  # refused before any work: onto an input, a run, an existing file
        _output_target(args.csv, "--csv", (args.file, args.budget), args.overwrite)
        _writable_folder(args.csv.parent, "--csv")
    recording = _load(args)
    analysis = analyze(
        recording,
        estimator=args.estimator,
        segments=args.segments,
        probability=args.coverage,
        rule="seed" if args.seed_rule else "gum",
        tolerance_percent=args.tolerance,
    )
    results = analysis.results
    status = analysis.status or "unknown"  # a CSV recording carries no status
    if args.csv:
        table = _csv_with_status(results.to_csv(), status)
        try:
            write_new(args.csv, table, overwrite=args.overwrite)
        except FileExistsRefusal as exc:
            raise UsageError(f"--csv: {exc} (--overwrite replaces it)") from None
    if args.json:
        note = status_warning(analysis.status)
        if note:
            print(f"accelcal analyze: warning: {note}", file=sys.stderr)
        print(json.dumps({"status": status, **results.to_dict(), **_reanalysed(args)}, indent=2))
    else:
        print_results(results, recording.source, analysis.status)
    return EXIT_OK


def _reanalysed(args: argparse.Namespace) -> dict:
    """The re-analysis settings applied to a stored HDF5 recording (empty for CSV)."""
    if args.file.suffix.lower() not in (".h5", ".hdf5") and not args.file.is_dir():
        return {}
    applied = {
        "reference_frequency_hz": args.reference_frequency,
        "settle_periods_dropped": args.settle_periods,
        "mains_frequency_hz": args.mains,
    }
    applied = {k: v for k, v in applied.items() if v is not None}
    return {"reanalysis": applied} if applied else {}


def _output_target(
    target: Path, option: str, inputs: tuple[Path | None, ...], overwrite: bool
) -> None:
    """UsageError naming `option` when `target` is an input, inside a run folder, or exists
    without --overwrite."""
    from app.records.run_folder import refuse_in_run_folder

    try:
        check_target(target, inputs=inputs, overwrite=overwrite)
        refuse_in_run_folder(target)
    except FileExistsRefusal as exc:
        raise UsageError(f"{option}: {exc} (--overwrite replaces it)") from None
    except ValueError as exc:
        raise UsageError(f"{option}: {exc}") from None


def _csv_with_status(text: str, status: str) -> str:
    """Per-line results CSV with a last column: the status of the recording analysed."""
    rows = list(csv.reader(io.StringIO(text)))
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow([*rows[0], "recording_status"])
    writer.writerows([*row, status] for row in rows[1:])
    return out.getvalue()


def print_results(results: Results, source: str = "", status: str | None = None) -> None:
    """Human-readable results: reference sensitivity, per-line table, warnings; `status` (of
    the recording analysed) shown unless complete or unknown."""
    r = results.reference
    value, u = fmt.round_gum(r.sensitivity_mv_per_ms2, r.expanded_uncertainty_mv_per_ms2)
    shown = f" ({status} recording)" if status not in (None, RunStatus.COMPLETE) else ""
    print(
        f"{source}{shown}: {results.periods} {'periods' if results.periods != 1 else 'period'}, "
        f"estimator {results.estimator}"
    )
    print(
        f"Reference sensitivity at {r.frequency_hz:g} Hz: {value} mV/(m/s^2) "
        f"({r.sensitivity_db:.2f} dB re 1 mV/(m/s^2)), U = {u} mV/(m/s^2) "
        f"(k = {r.coverage_factor:.2f}, p = {100 * r.coverage_probability:.2f} %)"
    )
    rows = []
    for ln in results.lines:
        s, us = fmt.round_gum(ln.sensitivity_mv_per_ms2, ln.expanded_uncertainty_mv_per_ms2)
        rows.append(
            [
                f"{ln.nominal_frequency_hz:g}",
                f"{ln.frequency_hz:g}",
                s,
                us,
                f"{ln.deviation_percent:+.2f}",
                f"{ln.phase_deg:.2f}" if results.phase_corrected_for_skew else "n/c",
                f"{ln.phase_expanded_uncertainty_deg:.2f}",
                fmt.percent(ln.relative_expanded_uncertainty),
                f"{ln.coverage_factor:.2f}",
                f"{ln.coherence:.4f}",
                f"{ln.dut_snr_db:.0f}",
                ln.iso_verdict,
            ]
        )
    print(
        fmt.table(
            [
                "nominal Hz",
                "actual Hz",
                "S mV/(m/s^2)",
                "U",
                "dev %",
                "phase deg",
                "U deg",
                "U rel",
                "k",
                "coherence",
                "SNR dB",
                "ISO 16063-21",
            ],
            rows,
        )
    )
    for warning in results.warnings:
        print(f"warning: {warning}")
    if not results.phase_corrected_for_skew:
        print("phase (n/c): not corrected for skew (inter-channel delay unknown); not stated")
    if results.verdict is not None:
        print(f"VERDICT: {results.verdict}")
        for reason in results.verdict_reasons:
            print(f"  - {reason}")


def parse_percent(text: str, option: str) -> float:
    """'0.2%' -> 0.002; '0.002' -> 0.002."""
    try:
        value = float(text[:-1]) / 100 if text.strip().endswith("%") else float(text)
    except ValueError:
        raise UsageError(f"{option}: {text!r} is not a number or percentage") from None
    low, high = TARGET_UA
    if not (math.isfinite(value) and low < value <= high):
        raise UsageError(f"{option}: must be in (0, 100 %], got {text!r}")
    return value


def parse_seconds(text: str, option: str) -> float:
    """'30s', '2min', '45' -> seconds."""
    value = text.strip().lower()
    scale = 1.0
    for suffix, factor in (("min", 60.0), ("ms", 1e-3), ("s", 1.0), ("h", 3600.0)):
        if value.endswith(suffix):
            value, scale = value[: -len(suffix)], factor
            break
    try:
        seconds = float(value) * scale
    except ValueError:
        raise UsageError(f"{option}: {text!r} is not a duration (e.g. 30s)") from None
    if not (math.isfinite(seconds) and 0 < seconds <= MAX_TIME_S):
        raise UsageError(f"{option}: must be in (0, 24 h], got {text!r}")
    return seconds


def _faults(texts: list[str]) -> tuple[Fault, ...]:
    """--fault KIND@SECONDS options as faults of the simulated stand."""
    from sim.stand import Fault

    try:
        return tuple(Fault.parse(text) for text in texts)
    except ValueError as exc:
        raise UsageError(str(exc)) from None


def _dut_from_teds(args: argparse.Namespace, use_records: bool, notes: list[str]) -> str | None:
    """run --teds: the DUT's TEDS read on the stand; the records' sensor of that identity
    (its serial, for --sensor), else the TEDS serial and nominal sensitivity."""
    from app.stand import teds as teds_io
    from hardware.teds import TedsError, decode

    try:
        teds = decode(teds_io.open_port(args.stand, args.dut, args.seed).read())
    except TedsError as exc:
        raise UsageError(f"--teds: {exc}") from None
    identity = teds.basic.identity
    notes.append(f"TEDS identity {identity}")
    if use_records:
        from app.records.db.engine import open_engine
        from app.records.db.lab import Lab

        sensor = Lab(open_engine(args.db)).sensor_by_teds(identity)
        if args.sensor and args.sensor != sensor.serial:
            raise UsageError(f"--sensor: {args.sensor!r} is not the TEDS sensor {sensor.serial!r}")
        return sensor.serial
    args.dut_id = args.dut_id or f"TEDS-{identity.replace('/', '-')}"
    if teds.accelerometer is not None and args.nominal_sensitivity is None:
        args.nominal_sensitivity = teds.accelerometer.sensitivity_mv_per_ms2
    return args.sensor


def cmd_run(args: argparse.Namespace) -> int:
    from app.procedure.run import RunRequest, execute
    from dsp.spectral import check_periods

    if args.sim and args.stand:
        raise UsageError("--sim and --stand: choose one")
    try:
        check_periods(args.estimator, args.periods)  # issue 13 point 5 (dsp.spectral)
    except ValueError as exc:
        raise UsageError(f"--{exc}") from None
    faults = _faults(args.fault)
    levels = _levels(args.levels) if args.levels else None
    target = parse_percent(args.target_ua, "--target-ua") if args.target_ua else None
    max_time = parse_seconds(args.max_time, "--max-time") if args.max_time else None
    _writable_folder(args.out, "--out")
    use_records = bool(args.sensor or args.db or os.environ.get("ACCELCAL_DB"))
    notes: list[str] = []
    if args.teds:
        args.sensor = _dut_from_teds(args, use_records, notes)
    if args.sensor:
        from app.records.db.runs import sensor_defaults

        sensor = sensor_defaults(args.sensor, args.db)
        if args.dut_id is not None and args.dut_id != sensor.serial:
            raise UsageError(f"--dut-id: {args.dut_id!r} differs from --sensor {sensor.serial!r}")
        args.dut_id = sensor.serial
        args.nominal_sensitivity = args.nominal_sensitivity or sensor.nominal_mv_per_ms2
        args.tolerance = args.tolerance if args.tolerance is not None else sensor.tolerance_percent
        args.level = args.level if args.level is not None else sensor.level_ms2
        args.preset = args.preset or (sensor.preset if sensor.preset in PRESETS else None)
        notes.append(f"sensor {sensor.serial}: {sensor.description}")
    if use_records:
        from datetime import UTC, datetime

        from app.records.db.runs import check_reference_due
        from app.stand import config as stand_config

        reference_id = stand_config.load(args.stand).reference.id
        note = check_reference_due(
            reference_id,
            args.db,
            today=datetime.now(UTC).date(),
            override_reason=args.reference_override,
        )
        if note:
            notes.append(note)
    if args.level is None:
        args.level = 5.0
    for note in notes:
        print(note, file=sys.stderr)
    request = RunRequest(
        stand_file=args.stand,
        dut=args.dut,
        dut_id=args.dut_id,
        preset=args.preset,
        level_ms2=args.level,
        periods=args.periods,
        target_type_a=target,
        max_acquisition_s=max_time,
        estimator=args.estimator,
        mode=args.mode,
        tolerance_percent=args.tolerance,
        nominal_mv_per_ms2=args.nominal_sensitivity,
        seed=args.seed,
        paced=args.paced,
        faults=faults,
        out=args.out,
        dut_mass_g=args.dut_mass,
        stored_response=not args.fresh_response,
    )
    progress = None if args.json else TerminalProgress()
    if levels is not None:
        return run_levels(request, levels, args, progress)
    finished = execute(request, listener=progress)
    if progress is not None:
        progress.close()
    record = finished.record
    if use_records and record.run_id:
        from app.records.db.runs import index_finished_run

        print(index_finished_run(args.out / str(record.run_id), args.db), file=sys.stderr)
    if args.json:
        print(record.to_json())
    else:
        if finished.results is not None:
            print_results(finished.results, record.run_id or "")
        print(f"run folder: {args.out / str(record.run_id)}")
        print(
            f"status: {record.status}"
            + (f" ({record.abort_reason})" if record.abort_reason else "")
            + f"; excitation {record.excitation_time_s:.1f} s; output now "
            + (f"{record.final_output_v:g} V" if record.final_output_v is not None else "unknown")
        )
    return EXIT_OK if record.complete else EXIT_ABORTED


def _levels(text: str) -> list[float]:
    """--levels: a comma-separated list, every item within the bounds of --level."""
    levels = []
    for item in text.split(","):
        if not item.strip():
            raise UsageError(f"--levels: {text!r} has an empty item")
        try:
            levels.append(LEVEL(item.strip()))
        except argparse.ArgumentTypeError as exc:
            raise UsageError(f"--levels: {item.strip()!r}: {exc}") from None
    return levels


def run_levels(request: RunRequest, levels: list[float], args: argparse.Namespace, progress) -> int:
    """`accelcal run --levels ...`: one run per level and the sweep summary."""
    from app.procedure.sweep import run_sweep

    try:
        sweep = run_sweep(request, levels, progress)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    if progress is not None:
        progress.close()
    summary = sweep.summary
    if args.json:
        print(json.dumps(summary, indent=2))
    elif "sensitivity_mv_per_ms2" in summary:
        done = summary["levels_ms2"][: len(summary["sensitivity_mv_per_ms2"])]
        rows = [
            [
                f"{f:g}",
                *(f"{row[k]:.4f}" for row in summary["sensitivity_mv_per_ms2"]),
                f"{summary['linearity_percent'][k]:.3f}",
            ]
            for k, f in enumerate(summary["frequencies_hz"])
        ]
        print("Sensitivity in mV/(m/s^2) against frequency and level (m/s^2 per line)")
        print(fmt.table(["Hz", *(f"{lv:g}" for lv in done), "linearity %"], rows))
        print(
            f"Linearity: {summary['reference_linearity_percent']:.3f} % at "
            f"{summary['reference_frequency_hz']:g} Hz, worst "
            f"{summary['worst_linearity_percent']:.3f} % at "
            f"{summary['worst_linearity_frequency_hz']:g} Hz"
        )
    if not args.json:
        print(f"sweep summary: {summary['path']}; runs: {', '.join(map(str, summary['run_ids']))}")
        if summary["abort_reason"]:
            print(f"status: aborted ({summary['abort_reason']})")
    return EXIT_OK if sweep.complete else EXIT_ABORTED


class TerminalProgress:
    """One line of progress on stderr: state, period, worst type A so far, worst line."""

    def __init__(self) -> None:
        self._tty = sys.stderr.isatty()

    def __call__(self, event) -> None:
        from app.procedure import EqualisationStep, PeriodEstimate, StateChanged, WarningRaised

        if isinstance(event, StateChanged):
            self._line(f"[{event.state}] {event.message}", final=True)
        elif isinstance(event, EqualisationStep):
            self._line(
                f"  equalisation {event.iteration}: worst line {100 * event.worst:.2f} %", True
            )
        elif isinstance(event, PeriodEstimate):
            lines = event.results.lines
            worst = max(lines, key=lambda ln: ln.relative_type_a)
            bar = "#" * min(event.periods, 40)
            self._line(
                f"  period {event.periods:3d} {bar:<20} type A worst "
                f"{100 * worst.relative_type_a:.3f} % at {worst.nominal_frequency_hz:g} Hz",
                final=not self._tty,
            )
        elif isinstance(event, WarningRaised):
            self._line(f"  warning: {event.text}", final=True)

    def _line(self, text: str, final: bool) -> None:
        if self._tty:
            sys.stderr.write("\r\033[K" + text + ("\n" if final else ""))
        else:
            sys.stderr.write(text + "\n")
        sys.stderr.flush()

    def close(self) -> None:
        if self._tty:
            sys.stderr.write("\n")


def cmd_devices(args: argparse.Namespace) -> int:
    from hardware.discovery import describe, list_ni_devices

    print(describe())
    try:
        return EXIT_OK if list_ni_devices() else EXIT_FAILURE
    except HardwareError:
        return EXIT_FAILURE  # no NI-DAQmx driver (said above)


def cmd_gui(args: argparse.Namespace) -> int:
    if args.sim and args.stand:
        raise UsageError("--sim and --stand: choose one")
    _writable_folder(args.out, "--out")
    from app.gui import run_gui  # Qt only once the options are good

    return run_gui(
        stand_file=args.stand,
        out=args.out,
        paced=not args.unpaced,
        seed=args.seed,
        autorun=args.autorun,
        screenshot=args.screenshot,
        quit_after_run=args.quit_after_run,
        dut=args.dut,
        sim=args.sim,
        db=args.db,
    )


def cmd_certificate(args: argparse.Namespace) -> int:
    from app.certificate import CertificateInfo, issue
    from app.records.run_folder import is_run_folder

    info = CertificateInfo(
        customer=args.customer,
        customer_address=args.customer_address,
        authorised_by=args.authorised_by,
        dut_model=args.dut_model,
        dut_serial=args.dut_serial,
        dut_type=args.dut_type,
        temperature_c=args.temperature,
        mounting=args.mounting,
        certificate_number=args.certificate_number,
        issue_date=args.issue_date,
        notes=args.notes,
    )
    out = args.out or (args.run / "certificate.pdf")
    signer = None
    if args.sign is not None:
        from app.certificate.sign import Signer, SigningError

        try:
            signer = Signer.load(args.sign)
        except SigningError as exc:
            raise UsageError(str(exc)) from None
    if args.out is not None and not is_run_folder(args.out.parent):  # a run's own: see issue()
        _writable_folder(args.out.parent, "--out")
    if args.db or os.environ.get("ACCELCAL_DB"):
        from app.records.db.audit import current_actor
        from app.records.db.certify import issue_registered

        issued = issue_registered(
            args.run,
            info,
            out,
            url=args.db,
            prepared_by=args.prepared_by or current_actor(),
            sweep_path=args.sweep,
            replaces=args.replaces,
            reason=args.reason,
            signer=signer,
        )
    elif args.prepared_by or args.replaces or args.reason:
        raise UsageError("--prepared-by, --replaces, --reason: need the records (--db URL)")
    else:
        issued = issue(args.run, info, out, args.sweep, signer)
    print(f"certificate {issued.number}: {out}")
    from app.certificate import dcc_path

    if dcc_path(out).exists():
        print(f"digital calibration certificate (DCC 3.3.0, in the PDF too): {dcc_path(out)}")
    else:
        print("no digital calibration certificate: the stand file names no laboratory.country")
    return EXIT_OK


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


def cmd_simulate(args: argparse.Namespace) -> int:
    from app.stand.simulate import simulate

    if args.list:
        return print_catalogue(args.json)
    if args.out is None:
        raise UsageError("--out: the recording to write is required (or --list)")
    if args.out.suffix.lower() not in (".h5", ".hdf5"):
        raise UsageError(f"--out: {args.out} must end in .h5 or .hdf5")
    faults = _faults(args.fault)
    _writable_folder(args.out.parent, "--out")
    try:
        run = simulate(
            args.out,
            dut=args.dut,
            level_ms2=args.level,
            periods=args.periods,
            seed=args.seed,
            settle=args.settle,
            faults=faults,
            overwrite=args.overwrite,
        )
    except HardwareError:
        print(
            f"accelcal simulate: the recording so far, marked aborted: {args.out}", file=sys.stderr
        )
        raise
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


def print_catalogue(as_json: bool) -> int:
    """The simulated stand's exciter, reference and DUTs."""
    stand = StandModel()
    entries: dict[str, Any] = {
        "exciter": {
            "name": stand.exciter.name,
            "suspension_resonance_hz": stand.exciter.suspension_hz,
            "axial_resonance_hz": stand.exciter.axial_resonance_hz,
            "stroke_peak_to_peak_mm": 1e3 * stand.exciter.stroke_peak_to_peak_m,
            "midband_ms2_per_v": stand.exciter.midband_ms2_per_v,
        },
        "reference": {
            "description": stand.reference.description,
            "sensitivity_mv_per_ms2": stand.reference.sensitivity_mv_per_ms2,
            "conditioning_gain": stand.reference_gain,
        },
        "duts": {
            name: {
                "description": model.description,
                "kind": model.kind,
                "sensitivity_mv_per_ms2": 0.0 if model.dead else model.sensitivity_mv_per_ms2,
            }
            for name, model in DUT_CATALOGUE.items()
        },
    }
    if as_json:
        print(json.dumps(entries, indent=2))
        return EXIT_OK
    ex = entries["exciter"]
    print(
        f"exciter: {ex['name']}: suspension resonance {ex['suspension_resonance_hz']:g} Hz, "
        f"axial resonance {ex['axial_resonance_hz']:g} Hz, stroke "
        f"{ex['stroke_peak_to_peak_mm']:g} mm p-p"
    )
    print(f"reference: {stand.reference.description}")
    print("DUTs (--dut NAME):")
    for name, entry in entries["duts"].items():
        print(f"  {name:<11} {entry['description']}")
    return EXIT_OK


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


def cmd_verify(args: argparse.Namespace) -> int:
    """accelcal verify: exit 0 when every check holds, 2 when one fails or the input is bad."""
    from app.certificate.sign import verify

    for option, path in (("pdf", args.pdf), ("--trust", args.trust)):
        if path is not None and not path.is_file():
            raise UsageError(f"{option}: no such file {path}")
    if args.run is not None and not args.run.is_dir():
        raise UsageError(f"--run: no such run folder {args.run}")
    report = verify(args.pdf, args.run, args.trust)
    for name, ok, detail in report.checks:
        print(f"{'ok  ' if ok else 'FAIL'} {name}" + (f": {detail}" if detail else ""))
    print("certificate verified" if report.ok else "certificate NOT verified")
    return EXIT_OK if report.ok else EXIT_BAD_INPUT


COMMANDS = {
    "plan": cmd_plan,
    "analyze": cmd_analyze,
    "simulate": cmd_simulate,
    "run": cmd_run,
    "show": cmd_show,
    "certificate": cmd_certificate,
    "devices": cmd_devices,
    "gui": cmd_gui,
    "verify": cmd_verify,
    "teds": cmd_teds,
}


if __name__ == "__main__":
    raise SystemExit(main())
