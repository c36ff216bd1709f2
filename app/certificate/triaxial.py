"""The certificate section of a triaxial sensor (issue 36 point 3), as printed: from a
dsp.triaxial.TriaxialResult, every number rounded once, here (GUM 7.2.6: U to two significant
digits, the value to the same place; app.formatting.round_gum), for the PDF
(app.certificate.triaxial_pdf) and the DCC (app.certificate.triaxial_dcc) alike.

Per axis and line: the characteristic (sensitivity in mV/(m/s^2), deviation from the
reference-frequency sensitivity in %, phase in degrees) and the transverse statements (each
ratio's magnitude in % of the main axis and its phase in degrees, the largest transverse
sensitivity in % and its angle in degrees), each with its U; the 3 x 3 matrix at the reference
frequency (magnitude in mV/(m/s^2), phase in degrees, with U); per axis the largest
transverse sensitivity at the reference frequency with its direction.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from app import formatting as fmt
from app.certificate.info import CertificateError
from dsp.errors import InputRefused
from dsp.triaxial import AXES, AxisResult, Stated, TriaxialResult, triaxial_result
from dsp.uncertainty import Budget

if TYPE_CHECKING:
    from app.certificate.load import StoredRun

NOT_STATED = fmt.NOT_STATED_SHORT
SECTION_TITLE = "Triaxial sensor: main axes, transverse sensitivity and sensitivity matrix"


@dataclass(frozen=True)
class Printed:
    """A value and its U as printed (GUM rounding), with k; 'n/s' when not stated."""

    value: str
    expanded: str
    k: str

    @property
    def stated(self) -> bool:
        return self.value != NOT_STATED


def printed(value: float, expanded: float, k: float) -> Printed:
    """`value` with its U rounded per GUM 7.2.6 and k to two decimals; not stated (n/s) when
    either is not finite or U is not positive."""
    if not (math.isfinite(value) and math.isfinite(expanded) and expanded > 0):
        return Printed(NOT_STATED, NOT_STATED, NOT_STATED)
    text, u = fmt.round_gum(value, expanded)
    return Printed(text, u, f"{k:.2f}" if math.isfinite(k) else NOT_STATED)


def _at(s: Stated, i: int) -> Printed:
    return printed(*s.at(i))


@dataclass(frozen=True)
class AxisLine:
    """One line of one axis, printed: frequency (Hz), sensitivity (mV/(m/s^2)), deviation
    (%), phase (degrees), the ratios towards the other two axes (%, degrees), the largest
    transverse sensitivity (%) and its angle (degrees)."""

    frequency: str
    sensitivity: Printed
    deviation: Printed
    phase: Printed
    ratio_k: Printed
    ratio_k_phase: Printed
    ratio_l: Printed
    ratio_l_phase: Printed
    largest: Printed
    angle: Printed


@dataclass(frozen=True)
class PrintedAxis:
    """An axis, printed: its name, the axes its ratios point to (k, l), and its lines."""

    axis: str
    towards_k: str
    towards_l: str
    lines: tuple[AxisLine, ...]
    largest_at_reference: Printed
    angle_at_reference: Printed


@dataclass(frozen=True)
class PrintedEntry:
    """S[row, column] at the reference frequency: magnitude (mV/(m/s^2)), phase (degrees)."""

    row: str
    column: str
    magnitude: Printed
    phase: Printed


@dataclass(frozen=True)
class PrintedTriaxial:
    """The whole section as printed."""

    reference_frequency: str
    coverage_probability: str
    axes: tuple[PrintedAxis, PrintedAxis, PrintedAxis]
    matrix: tuple[tuple[PrintedEntry, ...], ...]
    notes: tuple[str, ...]


def _axis(a: AxisResult, result: TriaxialResult) -> PrintedAxis:
    rk, rl = a.transverse
    lines = []
    for i, f in enumerate(result.frequency_hz):
        reference = i == result.reference_index
        deviation = (
            Printed("0", "0", _at(a.sensitivity_mv_per_ms2, i).k)
            if reference and _at(a.sensitivity_mv_per_ms2, i).stated
            else _at(a.deviation_percent, i)
        )
        lines.append(
            AxisLine(
                frequency=f"{f:g}",
                sensitivity=_at(a.sensitivity_mv_per_ms2, i),
                deviation=deviation,
                phase=_at(a.phase_deg, i) if a.phase_stated else printed(math.nan, 0, 0),
                ratio_k=_at(rk.magnitude_percent, i),
                ratio_k_phase=_at(rk.phase_deg, i),
                ratio_l=_at(rl.magnitude_percent, i),
                ratio_l_phase=_at(rl.phase_deg, i),
                largest=_at(a.largest_percent, i),
                angle=_at(a.angle_deg, i),
            )
        )
    r = result.reference_index
    return PrintedAxis(
        axis=a.axis.value,
        towards_k=rk.towards.value,
        towards_l=rl.towards.value,
        lines=tuple(lines),
        largest_at_reference=_at(a.largest_percent, r),
        angle_at_reference=_at(a.angle_deg, r),
    )


def printed_triaxial(result: TriaxialResult) -> PrintedTriaxial:
    """The section of `result`, every number rounded once."""
    axes = tuple(_axis(a, result) for a in result.axes)
    matrix = tuple(
        tuple(
            PrintedEntry(
                e.row.value,
                e.column.value,
                printed(e.magnitude_mv_per_ms2, e.magnitude_expanded, e.magnitude_k),
                printed(e.phase_deg, e.phase_expanded_deg, e.phase_k),
            )
            for e in row
        )
        for row in result.matrix
    )
    notes = [*result.warnings]
    skipped = sorted({reason for reason in result.not_stated if reason})
    for reason in skipped:
        lines = [
            f"{f:g} Hz"
            for f, why in zip(result.nominal_frequency_hz, result.not_stated, strict=True)
            if why == reason
        ]
        notes.append(f"{', '.join(lines)}: {reason}")
    return PrintedTriaxial(
        reference_frequency=f"{result.reference_frequency_hz:g}",
        coverage_probability=f"{100 * result.coverage_probability:.2f}",
        axes=(axes[0], axes[1], axes[2]),
        matrix=matrix,
        notes=tuple(notes),
    )


def direction_text(axis: PrintedAxis) -> str:
    """The largest transverse sensitivity of an axis at the reference frequency in words."""
    big, angle = axis.largest_at_reference, axis.angle_at_reference
    if not big.stated:
        return f"axis {axis.axis}: not stated"
    where = (
        f" at {angle.value}° ± {angle.expanded}° from +{axis.towards_k} towards +{axis.towards_l}"
        if angle.stated
        else " (direction not stated)"
    )
    return f"axis {axis.axis}: {big.value} % ± {big.expanded} % of its sensitivity{where}"


def stored_triaxial(
    folders: Mapping[str, Mapping[str, str | Path]], table_transverse: Budget
) -> TriaxialResult:
    """The TriaxialResult of nine stored runs, `folders[orientation][channel]` (x, y, z each),
    each loaded as a certificate reads it (app.certificate.load: verified, complete; the
    main-axis runs certifiable, a cross run's own warnings not refusing it: its signal is the
    transverse one). CertificateError naming the orientation and channel when a run cannot
    be certified, when the runs' budgets differ in their shared terms (each run's own budget is
    used: its measured ADC and hum terms are its own), or when one channel's three runs name
    different sensors; dsp.triaxial's refusals (InputRefused) for the rest."""
    from app.certificate.load import load_stored_run

    names = [a.value for a in AXES]
    runs: dict[str, dict[str, StoredRun]] = {}
    budgets: dict[tuple[str, str], Budget] = {}
    for o in names:
        runs[o] = {}
        for j in names:
            path = folders.get(o, {}).get(j)
            where = f"triaxial: orientation {o!r}, channel {j!r}"
            if path is None:
                raise CertificateError(f"{where}: no run folder given")
            try:  # a cross channel's signal is the transverse one: its own warnings (U over
                # the ISO limit, hum "distortion" at its small signal) do not refuse it
                run = load_stored_run(path, certifiable=o == j)
            except CertificateError as exc:
                raise CertificateError(f"{where}: {exc}") from None
            runs[o][j] = run
            budgets[(o, j)] = run.budget
    first = budgets[("x", "x")]
    for j in names:
        ids = {o: _dut_id(runs[o][j].record.dut) for o in names}
        if len(set(ids.values())) > 1:
            listed = ", ".join(f"{o}: {i!r}" for o, i in ids.items())
            raise CertificateError(
                f"triaxial: channel {j!r}: its runs name different sensors ({listed})"
            )
    results = {o: {j: runs[o][j].results for j in names} for o in names}
    try:  # each run's own budget (its measured ADC and hum terms): the shared terms must agree
        return triaxial_result(results, first, table_transverse, budgets)
    except InputRefused as exc:
        raise CertificateError(str(exc)) from None


def _dut_id(dut: object) -> str | None:
    return getattr(dut, "id", None)
