"""`accelcal plan`: a frequency plan, its checks and predicted peaks."""

from __future__ import annotations

import argparse
import json

from app.cli.exits import EXIT_OK, UsageError
from app.cli.options import parse_frequencies
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
    """The plan of the options; with --profile, --corner or --exciter (issue 26) clipped by the
    stroke (the exciter's, else the default stand's) and refused when the whole plan's travel
    exceeds it (exit 2 naming the line and the predicted displacement)."""
    plan = _plan(args)
    report = plan_report(plan)
    if args.json:
        print(json.dumps(report, indent=2))
        return EXIT_OK
    print_plan(plan, report)
    return EXIT_OK


def _stroke(exciter: str | None) -> float:
    """Peak-to-peak stroke in m: the simulated exciter's, else the default stand file's."""
    if exciter is not None:
        from app.stand.simulated import exciter_stroke_m

        return exciter_stroke_m(exciter)
    return builtin_stroke_m()


def builtin_stroke_m() -> float:
    """The built-in simulated stand's travel (m peak to peak), `load().limits`' figure, read
    from its file alone: `plan` does not import app.stand.config (its budget, reference chain
    and channels) for one number (issue 34 point 3; a test holds the two equal)."""
    import tomllib
    from importlib import resources

    text = resources.files("sim").joinpath("stand.toml").read_text(encoding="utf-8")
    return float(tomllib.loads(text)["limits"]["displacement_peak_to_peak_m"])


def _plan(args: argparse.Namespace) -> Plan:
    from app.procedure.planning import PlanRequest, build_plan

    if args.profile != "acceleration" and args.corner is None:
        raise UsageError(f"--profile {args.profile}: needs --corner (Hz)")
    return build_plan(
        PlanRequest(
            preset=args.preset or "piezo",
            frequencies_hz=tuple(parse_frequencies(args.frequencies)) if args.frequencies else None,
            sample_rate_hz=args.sample_rate,
            period_samples=args.period,
            level_ms2=args.level,
            reference_frequency_hz=args.reference_frequency,
            mains_frequency_hz=args.mains if args.mains is not None else 50.0,
            profile=args.profile,
            corner_hz=args.corner,
            shift_mains_lines=not args.exact_mains_bins,
        ),
        stroke_peak_to_peak_m=_stroke(args.exciter),
    )
