"""`accelcal plan`: a frequency plan, its checks and predicted peaks."""

from __future__ import annotations

import argparse
import json

from app import formatting as fmt
from app.cli.exits import EXIT_OK
from app.cli.options import plan_from_options
from dsp.multisine import Plan


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
    plan = plan_from_options(args, optimise=True)
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
