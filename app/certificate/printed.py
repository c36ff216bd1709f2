"""A line of the results as the certificate prints it: the numbers (floats, in the units of
their names) and their printed strings, rounded once, here, for the PDF's table, the DCC and
`accelcal verify` alike.

Rounding: a value with its expanded uncertainty per GUM 7.2.6 (app.formatting.round_gum: U to
two significant digits, the value to the same decimal place); the deviation and its U from
dsp.characteristic (the correlated model: common factors cancel).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import StrEnum

from app import formatting as fmt
from app.records.db.units import STANDARD_GRAVITY_MS2
from dsp.calibration import LineResult, Results
from dsp.characteristic import line_deviation_expanded_percent
from dsp.conformity import NOT_STATED


class Item(StrEnum):
    """A printed item of the certificate's first page (the names PrintedItems uses)."""

    NUMBER = "number"
    CUSTOMER = "customer"
    SERIAL = "serial"
    CALIBRATION_DATE = "calibration_date"
    ISSUE_DATE = "issue_date"
    RUN_ID = "run_id"
    SEAL = "seal"
    CHAIN_HEAD = "chain_head"
    VERDICT = "verdict"
    REPLACES = "replaces"  # an amendment: the number of the certificate it replaces
    AMENDMENT_REASON = "amendment_reason"  # and why


class Column(StrEnum):
    """A column of the results table, in the order printed (S in mV/g last, when printed)."""

    NOMINAL = "nominal"  # nominal frequency, Hz
    FREQUENCY = "f"  # actual frequency, Hz
    SENSITIVITY = "s"  # mV/(m/s^2)
    EXPANDED = "u"  # U of the sensitivity, mV/(m/s^2)
    DEVIATION = "dev"  # from the reference-frequency sensitivity, %
    DEVIATION_EXPANDED = "u_dev"  # U of the deviation (the characteristic's U), %
    DEVIATION_DB = "dev_db"  # the same in dB
    PHASE = "ph"  # degrees, or n/s
    PHASE_EXPANDED = "u_ph"  # degrees, or n/s
    RELATIVE = "u_rel"  # relative U of the sensitivity, %
    K = "k"  # coverage factor
    ISO = "iso"  # ISO 16063-21 verdict
    SENSITIVITY_G = "s_g"  # mV/g (models stated in mV/g only)


NOT_STATED_SHORT = fmt.NOT_STATED_SHORT
ISO_WORDS = {"within": "within", "over": "over", "n/a": "n/a", NOT_STATED: NOT_STATED_SHORT}


@dataclass(frozen=True)
class PrintedLine:
    """One line: each number as a float and as printed (the string fields, no unit)."""

    nominal_frequency_hz: float
    frequency_hz: float
    sensitivity_mv_per_ms2: float
    expanded_mv_per_ms2: float
    coverage_factor: float
    phase_deg: float
    phase_expanded_deg: float
    deviation_percent: float
    deviation_expanded_percent: float
    deviation_db: float
    relative_expanded_percent: float
    frequency: str
    sensitivity: str
    expanded: str
    k: str
    phase: str
    phase_expanded: str
    deviation: str
    deviation_expanded: str
    deviation_in_db: str
    relative_expanded: str
    iso_verdict: str
    tolerance_verdict: str | None


def round_signed(value: float, uncertainty: float) -> tuple[str, str]:
    """`value` with a sign and its U, rounded per GUM 7.2.6 (round_gum); without a usable U the
    value to two decimals and 'n/a'."""
    if not (math.isfinite(uncertainty) and uncertainty > 0 and math.isfinite(value)):
        return (fmt.signed(value, 2) if math.isfinite(value) else "n/a"), "n/a"
    text, u = fmt.round_gum(value, uncertainty)
    decimals = len(text.partition(".")[2])
    return fmt.signed(float(text), decimals), u


def is_reference_line(ln: LineResult) -> bool:
    """True for the reference line as stored since issue 32: its deviation and the deviation's
    U are exactly 0 (by definition); results stored before state the sensitivity's U there."""
    return ln.deviation_percent == 0.0 and ln.deviation_expanded_percent == 0.0


def printed_line(ln: LineResult) -> PrintedLine:
    """The printed form of one line of dsp.calibration.Results; a line that is not stated
    (outside the reference's calibrated range) prints "n/s" in every value and U cell."""
    if not ln.stated:
        return _not_stated(ln)
    s, u = fmt.round_gum(ln.sensitivity_mv_per_ms2, ln.expanded_uncertainty_mv_per_ms2)
    ph, u_ph = fmt.round_gum(ln.phase_deg, ln.phase_expanded_uncertainty_deg)
    u_dev = line_deviation_expanded_percent(ln)
    if is_reference_line(ln):  # 0 by definition, and so is its U (issue 32 point 7)
        dev, u_dev_text = "0", "0"
    else:
        dev, u_dev_text = round_signed(ln.deviation_percent, u_dev)
    rel = 100 * ln.relative_expanded_uncertainty
    return PrintedLine(
        nominal_frequency_hz=ln.nominal_frequency_hz,
        frequency_hz=ln.frequency_hz,
        sensitivity_mv_per_ms2=ln.sensitivity_mv_per_ms2,
        expanded_mv_per_ms2=ln.expanded_uncertainty_mv_per_ms2,
        coverage_factor=ln.coverage_factor,
        phase_deg=ln.phase_deg,
        phase_expanded_deg=ln.phase_expanded_uncertainty_deg,
        deviation_percent=ln.deviation_percent,
        deviation_expanded_percent=u_dev,
        deviation_db=ln.deviation_db,
        relative_expanded_percent=rel,
        frequency=f"{ln.frequency_hz:g}",
        sensitivity=s,
        expanded=u,
        k=f"{ln.coverage_factor:.2f}",
        phase=ph,
        phase_expanded=u_ph,
        deviation=dev,
        deviation_expanded=u_dev_text,
        deviation_in_db=fmt.signed(ln.deviation_db, 3),
        relative_expanded=fmt.significant(rel),
        iso_verdict=ISO_WORDS.get(ln.iso_verdict, ln.iso_verdict),
        tolerance_verdict=ln.tolerance_verdict,
    )


def _not_stated(ln: LineResult) -> PrintedLine:
    """A line that is not stated: its frequencies, NaN numbers, "n/s" strings."""
    nan = math.nan
    return PrintedLine(
        nominal_frequency_hz=ln.nominal_frequency_hz,
        frequency_hz=ln.frequency_hz,
        sensitivity_mv_per_ms2=nan,
        expanded_mv_per_ms2=nan,
        coverage_factor=nan,
        phase_deg=nan,
        phase_expanded_deg=nan,
        deviation_percent=nan,
        deviation_expanded_percent=nan,
        deviation_db=nan,
        relative_expanded_percent=nan,
        frequency=f"{ln.frequency_hz:g}",
        sensitivity=NOT_STATED_SHORT,
        expanded=NOT_STATED_SHORT,
        k=NOT_STATED_SHORT,
        phase=NOT_STATED_SHORT,
        phase_expanded=NOT_STATED_SHORT,
        deviation=NOT_STATED_SHORT,
        deviation_expanded=NOT_STATED_SHORT,
        deviation_in_db=NOT_STATED_SHORT,
        relative_expanded=NOT_STATED_SHORT,
        iso_verdict=NOT_STATED_SHORT,
        tolerance_verdict=ln.tolerance_verdict,
    )


def printed_lines(results: Results) -> tuple[PrintedLine, ...]:
    """Every line of `results` as printed, in order."""
    return tuple(printed_line(ln) for ln in results.lines)


def table_cells(
    line: PrintedLine, phase_stated: bool, in_g: bool = False
) -> tuple[tuple[Column, str], ...]:
    """The cells of `line` in the certificate's results table, in the order printed, each as
    (Column, text): the PDF draws these and `accelcal verify` compares the page with them (the
    phase "n/s" when not stated; with `in_g` last the sensitivity in mV/g, 1 g = 9.80665
    m/s^2, rounded as its mV/(m/s^2) value)."""
    in_mv_per_g: tuple[tuple[Column, str], ...] = ()
    if in_g and not math.isfinite(line.sensitivity_mv_per_ms2):
        in_mv_per_g = ((Column.SENSITIVITY_G, NOT_STATED_SHORT),)
    elif in_g:
        value, _ = fmt.round_gum(
            line.sensitivity_mv_per_ms2 * STANDARD_GRAVITY_MS2,
            line.expanded_mv_per_ms2 * STANDARD_GRAVITY_MS2,
        )
        in_mv_per_g = ((Column.SENSITIVITY_G, value),)
    return (
        (Column.NOMINAL, f"{line.nominal_frequency_hz:g}"),
        (Column.FREQUENCY, line.frequency),
        (Column.SENSITIVITY, line.sensitivity),
        (Column.EXPANDED, line.expanded),
        (Column.DEVIATION, line.deviation),
        (Column.DEVIATION_EXPANDED, line.deviation_expanded),
        (Column.DEVIATION_DB, line.deviation_in_db),
        (Column.PHASE, line.phase if phase_stated else NOT_STATED_SHORT),
        (Column.PHASE_EXPANDED, line.phase_expanded if phase_stated else NOT_STATED_SHORT),
        (Column.RELATIVE, line.relative_expanded),
        (Column.K, line.k),
        (Column.ISO, line.iso_verdict),
        *in_mv_per_g,
    )
