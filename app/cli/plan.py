"""`accelcal plan`: a frequency plan, its checks and predicted peaks."""

from __future__ import annotations

import argparse
import json

from app.cli.exits import EXIT_OK
from app.cli.options import plan_from_options
from app.cli.printers import print_plan
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
    print_plan(plan, report)
    return EXIT_OK
