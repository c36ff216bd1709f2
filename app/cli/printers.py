"""What the commands print for people: results tables, the plan, the simulated catalogue, the
progress line of a run, a sweep's table (units in the column heads)."""

from __future__ import annotations

import csv
import io
import json
import math
import re
import sys
from typing import TYPE_CHECKING, Any

from app import formatting as fmt
from app.io.csv_cells import csv_text
from app.io.vocabulary import RunStatus

if TYPE_CHECKING:
    from pathlib import Path

    from app.records.run_record import RunRecord
    from dsp.calibration import Results
    from dsp.multisine import Plan


def csv_with_status(text: str, status: str) -> str:
    """Per-line results CSV with a last column: the status of the recording analysed."""
    rows = list(csv.reader(io.StringIO(text)))
    return csv_text([[*rows[0], "recording_status"], *([*row, status] for row in rows[1:])])


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
        if not ln.stated:  # issue 32 point 5: no number with U, the reason below the table
            rows.append(
                [
                    f"{ln.nominal_frequency_hz:g}",
                    f"{ln.frequency_hz:g}",
                    *([fmt.NOT_STATED_SHORT] * 7),
                    fmt.coherence(ln.coherence),
                    f"{ln.dut_snr_db:.0f}",
                    ln.iso_verdict,
                ]
            )
            continue
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
                fmt.coherence(ln.coherence),
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
                "U vs ISO limit",
            ],
            rows,
        )
    )
    for warning in results.warnings:
        print(f"warning: {warning}")
    if results.cmc:  # without one, the blocking "no CMC" warning says so
        print(fmt.cmc_statement(results))
    for note in fmt.not_stated_notes(results.lines):
        print(note)
    if any(not math.isfinite(ln.coherence) for ln in results.lines):
        print(fmt.COHERENCE_NOT_AVAILABLE)
    if not results.phase_corrected_for_skew:
        print("phase (n/c): not corrected for skew (inter-channel delay unknown); not stated")
    if results.verdict is not None:
        print(f"VERDICT: {results.verdict}")
        for reason in results.verdict_reasons:
            print(f"  - {reason}")
    elif results.verdict_reasons:  # none given, and why (a triaxial sensor's cross channel)
        print("VERDICT: none")
        for reason in results.verdict_reasons:
            print(f"  - {reason}")


class TerminalProgress:
    """One line of progress on stderr: state, period i of n (or the share of the type A
    target), time left (s), worst type A so far; a stepped sine names its line, a sweep says
    which level of how many it is at (`levels`, m/s^2 in the order they run)."""

    def __init__(self, levels: list[float] | None = None) -> None:
        self._tty = sys.stderr.isatty()
        self._levels = levels
        self._runs = 0
        self._worst = ""  # the last estimate's worst line, shown with the next progress
        self._periods = 0

    def __call__(self, event) -> None:
        from app.procedure import (
            EqualisationStep,
            InputRanges,
            PeriodEstimate,
            Progress,
            State,
            StateChanged,
            WarningRaised,
        )

        if isinstance(event, StateChanged):
            if event.state == State.PREFLIGHT and self._levels:
                self._runs += 1
                level = self._levels[min(self._runs, len(self._levels)) - 1]
                self._line(
                    f"level {self._runs} of {len(self._levels)}: {level:g} m/s^2", final=True
                )
            self._line(f"[{event.state}] {event.message}".rstrip(), final=True)
        elif isinstance(event, EqualisationStep):
            self._line(
                f"  equalisation {event.iteration}: worst line {100 * event.worst:.2f} %", True
            )
        elif isinstance(event, PeriodEstimate):
            stated = [ln for ln in event.results.lines if math.isfinite(ln.relative_type_a)]
            lines = stated or event.results.lines  # a line not stated has no type A
            worst = max(lines, key=lambda ln: ln.relative_type_a)
            self._periods = event.periods
            self._worst = (
                f"type A worst {100 * worst.relative_type_a:.3f} % at "
                f"{worst.nominal_frequency_hz:g} Hz"
            )
        elif isinstance(event, Progress):
            self._line(self._progress_text(event), final=not self._tty)
        elif isinstance(event, WarningRaised):
            self._line(f"  warning: {event.text}", final=True)
        elif isinstance(event, InputRanges):
            self._line(f"  {event.text}", final=True)

    def _progress_text(self, event) -> str:
        """A progress event as one line: what is done of what, the share, the time left."""
        share = max(0.0, min(1.0, event.fraction))
        bar = "#" * round(20 * share)
        left = event.remaining_s
        if left is None and 0 < share < 1 and event.elapsed_s > 0:
            left = event.elapsed_s * (1 - share) / share  # at the pace so far
        time_left = f", about {left:.0f} s left" if left is not None and share < 1 else ""
        gauge = f"[{bar:<20}] {100 * share:3.0f} %{time_left}"
        if event.message.startswith("line "):  # the stepped sine: one line at a time
            return f"  {event.message} {gauge}"
        if not event.until_target and event.remaining_s is not None and share > 0:  # periods
            what = f"period {self._periods} of {round(self._periods / share)}"
        else:  # until the type A target: the share is how close it is (of the target)
            what = f"period {self._periods}, to the type A target"
        return f"  {what} {gauge}; {self._worst}"

    def _line(self, text: str, final: bool) -> None:
        if self._tty:
            sys.stderr.write("\r\033[K" + text + ("\n" if final else ""))
        else:
            sys.stderr.write(text + "\n")
        sys.stderr.flush()

    def close(self) -> None:
        if self._tty:
            sys.stderr.write("\n")


_WARNING_KINDS = (  # (one warning after "line X Hz: ", the grouped wording)
    (
        re.compile(r"the \w+ harmonic of line \S+ Hz lands on its bin"),
        "harmonics of other lines land on the bins of {lines} lines ({cases} cases): {labels} Hz;"
        " distortion adds to them",
    ),
    (
        re.compile(r"the \w+ alias about fs of line \S+ Hz lands on its bin"),
        "aliases about fs of other lines land on the bins of {lines} lines ({cases} cases): "
        "{labels} Hz; distortion adds to them",
    ),
    (
        re.compile(r"on the \w+ mains harmonic"),
        "{lines} lines on a mains harmonic: {labels} Hz; a periodic average does not remove "
        "hum; the default plan moves each one bin (kept by --exact-mains-bins)",
    ),
    (
        re.compile(r"moved one bin off the \w+ mains harmonic"),
        "{lines} lines moved one bin off a mains harmonic: {labels} Hz; each stated at its "
        "actual frequency (--exact-mains-bins keeps the exact bins)",
    ),
    (re.compile(r"snapped to "), "{lines} lines snapped to the bin grid: {labels} Hz"),
)
_LINE_PREFIX = re.compile(r"^line (\S+) Hz: (.*)$")


def grouped_warnings(warnings: tuple[str, ...] | list[str]) -> list[str]:
    """Plan warnings with one line per kind of several (the count and the lines affected, Hz,
    each named once); a kind met once and any other warning as they are."""
    groups: dict[int, list[str]] = {}
    originals: dict[int, list[str]] = {}
    out: list[tuple[int, str]] = []  # (kind or -1, text) in order of first appearance
    for text in warnings:
        match = _LINE_PREFIX.match(text)
        kind = next(
            (
                k
                for k, (pattern, _) in enumerate(_WARNING_KINDS)
                if match and pattern.match(match.group(2))
            ),
            None,
        )
        if kind is None or match is None:
            out.append((-1, text))
            continue
        if kind not in groups:
            groups[kind], originals[kind] = [], []
            out.append((kind, ""))
        originals[kind].append(text)
        if match.group(1) not in groups[kind]:
            groups[kind].append(match.group(1))
    lines = []
    for kind, text in out:
        if kind < 0:
            lines.append(text)
        elif len(originals[kind]) == 1:
            lines.append(originals[kind][0])
        else:
            labels = sorted(groups[kind], key=float)
            lines.append(
                _WARNING_KINDS[kind][1].format(
                    lines=len(labels), cases=len(originals[kind]), labels=", ".join(labels)
                )
            )
    return lines


def print_catalogue(entries: dict[str, Any], as_json: bool) -> None:
    """The simulated stand's exciter, reference and DUTs (app.stand.simulated)."""
    if as_json:
        print(json.dumps(entries, indent=2))
        return
    ex = entries["exciter"]
    print(
        f"exciter: {ex['name']}: suspension resonance {ex['suspension_resonance_hz']:g} Hz, "
        f"axial resonance {ex['axial_resonance_hz']:g} Hz, stroke "
        f"{ex['stroke_peak_to_peak_mm']:g} mm p-p"
    )
    print(f"reference: {entries['reference']['description']}")
    print("DUTs (--dut NAME):")
    for name, entry in entries["duts"].items():
        print(f"  {name:<11} {entry['description']}")


def print_plan(plan: Plan, report: dict[str, Any]) -> None:
    """A plan's lines (Hz, m/s^2 peak, rad), crest factors and predicted peaks (mm, mm/s)."""
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
    for warning in grouped_warnings(plan.warnings):
        print(f"warning: {warning}")


def print_sweep(summary: dict[str, Any]) -> None:
    """An amplitude sweep: sensitivity (mV/(m/s^2)) against frequency and level, linearity."""
    if "sensitivity_mv_per_ms2" in summary:
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
    print(f"sweep summary: {summary['path']}; runs: {', '.join(map(str, summary['run_ids']))}")
    if summary["abort_reason"]:
        print(f"status: aborted ({summary['abort_reason']})")


def print_run_end(record: RunRecord, results: Results | None, folder: Path) -> None:
    """A finished run: its results, its folder, its status and the drive's last output (V)."""
    if results is not None:
        print_results(results, record.run_id or "")
    print(f"run folder: {folder}")
    print(
        f"status: {record.status}"
        + (f" ({record.abort_reason})" if record.abort_reason else "")
        + f"; excitation {record.excitation_time_s:.1f} s; output now "
        + (f"{record.final_output_v:g} V" if record.final_output_v is not None else "unknown")
    )
