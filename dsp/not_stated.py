"""Lines stated with no value (issue 32 points 2 and 5): a line outside the reference's
calibrated range or too few LSB above the converter's step keeps its frequencies, coherence, SNR
and distortion, but no sensitivity, deviation, phase, U or verdict, and says why. Also reads the
run's own warnings back to find such lines (results stored before the rule kept numbers)."""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from dsp.conformity import NOT_STATED

if TYPE_CHECKING:
    from dsp.calibration import LineResult

__all__ = ["not_stated_line", "read_back_not_stated", "unresolved_lines"]

_NOT_STATED_FIELDS = (
    "sensitivity_mv_per_ms2",
    "sensitivity_db",
    "deviation_percent",
    "deviation_db",
    "phase_deg",
    "relative_type_a",
    "relative_type_b",
    "relative_standard_uncertainty",
    "relative_expanded_uncertainty",
    "expanded_uncertainty_mv_per_ms2",
    "coverage_factor",
    "effective_dof",
    "phase_expanded_uncertainty_deg",
    "phase_coverage_factor",
    "deviation_expanded_percent",
)


def not_stated_line(line: LineResult, reason: str) -> LineResult:
    """`line` with no value stated: sensitivity, deviation, phase and every U NaN, the ISO and
    tolerance verdicts "not stated", `reason` kept (the frequencies, coherence, SNR and
    distortion stay: they state no result)."""
    cleared: dict[str, Any] = dict.fromkeys(_NOT_STATED_FIELDS, math.nan)
    return dataclasses.replace(
        line,
        **cleared,
        iso_verdict=NOT_STATED,
        tolerance_verdict=None if line.tolerance_verdict is None else NOT_STATED,
        not_stated=reason,
        cmc_bounds="",  # no U stated, none bounded
    )


_REFUSED = re.compile(r"^line (\S+) Hz: outside the reference certificate \(([^)]*) Hz\): refused")
# dsp.resolution.LineResolution.warning: a line too few LSB above the converter's step
_UNRESOLVED = re.compile(
    r"^line (\S+) Hz: (\S+) channel (\S+) LSB on its \+-(\S+) V range \(< (\S+) LSB\): "
    r"resolution not stated"
)


def unresolved_lines(warnings: Sequence[str]) -> dict[str, str]:
    """The lines the warnings name as too few LSB above the converter's step (issue 32 point
    2), by frequency label (Hz, as `:g`), with the reason their values are not stated."""
    out: dict[str, str] = {}
    for text in warnings:
        match = _UNRESOLVED.match(text)
        if match:
            label, channel, lsb, range_v, least = match.groups()
            reason = (
                f"{channel} channel {lsb} LSB on its +-{range_v} V range, under the {least} LSB "
                "a stated line needs"
            )
            out[label] = f"{out[label]}; {reason}" if label in out else reason
    return out


def read_back_not_stated(
    lines: tuple[LineResult, ...], warnings: Sequence[str], reference_hz: float
) -> tuple[LineResult, ...]:
    """Results stored before issue 32 kept numbers for a line they warned "refused" (outside
    the reference's certificate) or too few LSB above the converter's step: such a line is read
    back as not stated (the reference line keeps its values: its warning blocks the run)."""
    refused: dict[str, str] = {}
    for text in warnings:
        match = _REFUSED.match(text)
        if match:
            span = match.group(2)
            refused[match.group(1)] = f"outside the reference's calibrated range ({span} Hz)"
    unresolved = unresolved_lines(warnings)
    if not refused and not unresolved:
        return lines
    out = []
    for ln in lines:
        nominal, actual = f"{ln.nominal_frequency_hz:g}", f"{ln.frequency_hz:g}"
        reason = refused.get(nominal) or (
            None
            if ln.nominal_frequency_hz == reference_hz
            else unresolved.get(actual) or unresolved.get(nominal)
        )
        out.append(not_stated_line(ln, reason) if ln.stated and reason else ln)
    return tuple(out)
