"""The DCC's part of a triaxial sensor (issue 36 point 3): per axis a result of parallel D-SI
lists (frequency; sensitivity, phase and deviation with U; the transverse ratios towards the
other two axes, magnitude and phase, with U; the largest transverse sensitivity and its angle
with U), the 3 x 3 sensitivity matrix at the reference frequency (each entry's magnitude and
phase with U) and the largest transverse sensitivity per axis at the reference frequency, all
with the numbers printed as the PDF prints them (app.certificate.triaxial).

refTypes as app.certificate.dcc names them: PTB's basic_ names where one exists, this
program's vib_ names otherwise; each axis result carries the id `triaxial-<axis>`, each matrix
entry `S-<row>-<column>`, so a reader finds them without matching English names. A line with
a statement that is not stated (n/s) is left out of its axis's lists and named in the result's
description. `extension(result)` is an app.certificate.dcc.Extension: it appends the results
to the measurement result's dcc:results before the DCC is validated against the schema.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

from app.certificate.dcc import (
    DCC_NS,
    REF_DEVIATION,
    REF_FREQUENCY,
    REF_MAGNITUDE,
    REF_PHASE,
    UNIT_DEGREE,
    UNIT_HZ,
    UNIT_PERCENT,
    UNIT_SENSITIVITY,
    DccError,
    Extension,
    _d,
    _list_quantity,
    _real,
    _text,
)
from app.certificate.info import CertificateInfo
from app.certificate.triaxial import AxisLine, Printed, PrintedAxis, printed_triaxial
from dsp.triaxial import TriaxialResult

REF_AXIS = "vib_triaxialAxisResponse"
REF_MATRIX = "vib_sensitivityMatrix"
REF_MATRIX_MAGNITUDE = "vib_sensitivityMatrixMagnitude basic_measuredValue"
REF_MATRIX_PHASE = "vib_sensitivityMatrixPhase basic_measuredValue"
REF_RATIO = "vib_transverseSensitivityRatio basic_measuredValue"
REF_RATIO_PHASE = "vib_transverseSensitivityPhase basic_measuredValue"
REF_LARGEST = "vib_transverseSensitivityMaximum basic_measuredValue"
REF_ANGLE = "vib_transverseSensitivityAngle basic_measuredValue"
REF_LARGEST_RESULT = "vib_transverseSensitivityMaximumAtReference"

_COLUMNS: tuple[tuple[str, str], ...] = (
    ("sensitivity", "s"),
    ("deviation", "dev"),
    ("phase", "ph"),
    ("ratio_k", "tk"),
    ("ratio_k_phase", "tk_ph"),
    ("ratio_l", "tl"),
    ("ratio_l_phase", "tl_ph"),
    ("largest", "max"),
    ("angle", "angle"),
)


def _complete(line: AxisLine) -> bool:
    return all(getattr(line, name).stated for name, _ in _COLUMNS)


def _uncertainty(cells: list[Printed], p: str) -> tuple[list[str], list[str], list[str]]:
    return [c.expanded for c in cells], [c.k for c in cells], [p] * len(cells)


def axis_result(parent: ET.Element, axis: PrintedAxis, p: str) -> None:
    """One axis's result: its lines' lists (only the lines with every statement stated)."""
    lines = [ln for ln in axis.lines if _complete(ln)]
    left = [ln.frequency for ln in axis.lines if not _complete(ln)]
    if not lines:
        raise DccError(f"triaxial DCC: axis {axis.axis} has no line with every value stated")
    result = _d(parent, "result", id=f"triaxial-{axis.axis}", refType=REF_AXIS)
    k, el = axis.towards_k, axis.towards_l
    _text(result, "name", f"Axis {axis.axis}: main-axis response and transverse sensitivity")
    if left:
        _text(
            result,
            "description",
            f"Lines not stated (some value of axis {axis.axis} not stated): {' '.join(left)} Hz",
        )
    data = _d(_d(result, "data"), "list")
    _list_quantity(
        data,
        "Excitation frequency",
        [ln.frequency for ln in lines],
        UNIT_HZ,
        ref_type=REF_FREQUENCY,
    )

    def column(name: str, label: str, unit: str, ref_type: str) -> None:
        cells = [getattr(ln, name) for ln in lines]
        _list_quantity(
            data, label, [c.value for c in cells], unit, _uncertainty(cells, p), ref_type
        )

    column(
        "sensitivity", f"Axis {axis.axis}: sensitivity magnitude", UNIT_SENSITIVITY, REF_MAGNITUDE
    )
    column(
        "deviation",
        f"Axis {axis.axis}: deviation from the sensitivity at the reference frequency",
        UNIT_PERCENT,
        REF_DEVIATION,
    )
    column("phase", f"Axis {axis.axis}: phase shift", UNIT_DEGREE, REF_PHASE)
    column(
        "ratio_k",
        f"Axis {axis.axis}: transverse sensitivity ratio towards {k}",
        UNIT_PERCENT,
        REF_RATIO,
    )
    column(
        "ratio_k_phase",
        f"Axis {axis.axis}: phase of the transverse sensitivity ratio towards {k}",
        UNIT_DEGREE,
        REF_RATIO_PHASE,
    )
    column(
        "ratio_l",
        f"Axis {axis.axis}: transverse sensitivity ratio towards {el}",
        UNIT_PERCENT,
        REF_RATIO,
    )
    column(
        "ratio_l_phase",
        f"Axis {axis.axis}: phase of the transverse sensitivity ratio towards {el}",
        UNIT_DEGREE,
        REF_RATIO_PHASE,
    )
    column(
        "largest", f"Axis {axis.axis}: largest transverse sensitivity", UNIT_PERCENT, REF_LARGEST
    )
    column(
        "angle",
        f"Axis {axis.axis}: angle of the largest transverse sensitivity from +{k} towards +{el}",
        UNIT_DEGREE,
        REF_ANGLE,
    )


def add_triaxial(results: ET.Element, result: TriaxialResult) -> None:
    """Append the triaxial results to a DCC's dcc:results element."""
    section = printed_triaxial(result)
    p = f"{result.coverage_probability:g}"
    matrix = _d(results, "result", id="triaxial-matrix", refType=REF_MATRIX)
    _text(
        matrix,
        "name",
        f"Sensitivity matrix at the reference frequency {section.reference_frequency} Hz",
    )
    _text(
        matrix,
        "description",
        "S[j, o]: the output of channel j per m/s2 along the sensor's axis o (measured with "
        "the exciter along o)",
    )
    data = _d(matrix, "data")
    _real(data, section.reference_frequency, UNIT_HZ, REF_FREQUENCY, "Reference frequency")
    for row in section.matrix:
        for e in row:
            if not (e.magnitude.stated and e.phase.stated):
                continue
            where = f"S[{e.row}, {e.column}]"
            _real(
                data,
                e.magnitude.value,
                UNIT_SENSITIVITY,
                REF_MATRIX_MAGNITUDE,
                f"{where} magnitude",
                (e.magnitude.expanded, e.magnitude.k, p),
            )
            quantity = data[-1]
            quantity.set("id", f"S-{e.row}-{e.column}")
            _real(
                data,
                e.phase.value,
                UNIT_DEGREE,
                REF_MATRIX_PHASE,
                f"{where} phase",
                (e.phase.expanded, e.phase.k, p),
            )
    largest = _d(results, "result", id="triaxial-largest", refType=REF_LARGEST_RESULT)
    _text(
        largest,
        "name",
        f"Largest transverse sensitivity per axis at {section.reference_frequency} Hz",
    )
    data = _d(largest, "data")
    for axis in section.axes:
        big, angle = axis.largest_at_reference, axis.angle_at_reference
        if big.stated:
            _real(
                data,
                big.value,
                UNIT_PERCENT,
                REF_LARGEST,
                f"Axis {axis.axis}: largest transverse sensitivity at the reference frequency",
                (big.expanded, big.k, p),
            )
        if angle.stated:
            _real(
                data,
                angle.value,
                UNIT_DEGREE,
                REF_ANGLE,
                f"Axis {axis.axis}: its angle at the reference frequency from "
                f"+{axis.towards_k} towards +{axis.towards_l}",
                (angle.expanded, angle.k, p),
            )
    for axis in section.axes:
        axis_result(results, axis, p)


def extension(result: TriaxialResult) -> Extension:
    """An app.certificate.dcc.build extension adding `result`'s section to the DCC."""

    def extend(admin: ET.Element, measurement: ET.Element, info: CertificateInfo) -> None:
        results = measurement.find(f"{{{DCC_NS}}}results")
        if results is None:
            raise DccError("triaxial DCC: the measurement result has no dcc:results")
        add_triaxial(results, result)

    return extend


def with_triaxial(base: Extension, info: CertificateInfo) -> Extension:
    """`base`, followed by the triaxial section when `info` carries a TriaxialResult."""
    result = info.triaxial
    if result is None:
        return base
    section = extension(result)

    def extend(admin: ET.Element, measurement: ET.Element, given: CertificateInfo) -> None:
        base(admin, measurement, given)
        section(admin, measurement, given)

    return extend
