"""What the commands print for people: results tables, the plan, the simulated catalogue, the
progress line of a run, a sweep's table (units in the column heads)."""

from __future__ import annotations

import csv
import io
import json
import sys
from typing import TYPE_CHECKING, Any

from app import formatting as fmt
from app.io.vocabulary import RunStatus

if TYPE_CHECKING:
    from pathlib import Path

    from app.records.run_record import RunRecord
    from dsp.calibration import Results
    from dsp.multisine import Plan


def csv_with_status(text: str, status: str) -> str:
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
    for warning in plan.warnings:
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
