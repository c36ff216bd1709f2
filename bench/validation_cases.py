"""Known-answer cases for docs/validation.md: the error found against the truth, the U stated
and the overall verdict, per case (issue 13).

Simulated-stand runs (the full procedure, closed-loop equalisation) are checked against the
truth group their recording.h5 carries; the skew cases are synthetic CSV recordings of a flat
10 mV/(m/s^2) DUT whose channel is sampled 2 us after (or before) the reference, analysed with
and without the delay. "error" is the largest |measured - true| over the lines, as a share of
the true value (magnitude) or in degrees (phase), with the U stated at that line; "|e|/U" is
the largest ratio over the lines (<= 1: every line within its U).

Run: python bench/validation_cases.py [--smoke]   (about a minute; prints a Markdown table)
"""

from __future__ import annotations

import dataclasses
import logging
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from app.io.hdf5 import Recording, read_recording
from app.procedure.analysis import analyze
from app.procedure.phase_store import stored_phases
from app.procedure.run import RunRequest, execute
from app.procedure.verdict import Band, Tolerances
from dsp.calibration import ReferenceChain, Results
from dsp.estimators import Estimator
from dsp.multisine import preset_plan
from dsp.uncertainty import Budget, Component, Distribution, Quantity
from tests.synthetic import make_recording

log = logging.getLogger("validation_cases")


@dataclass(frozen=True)
class Case:
    """One row of the table."""

    name: str
    magnitude: tuple[float, float, float]  # worst error %, U % there, worst |e|/U
    phase: tuple[float, float, float]  # worst error deg, U deg there, worst |e|/U
    verdict: str
    note: str


def _worst(error: np.ndarray, u: np.ndarray) -> tuple[float, float, float]:
    k = int(np.argmax(np.abs(error)))
    return float(abs(error[k])), float(u[k]), float(np.max(np.abs(error) / u))


def against_truth(results: Results, true_s: np.ndarray, true_phase: np.ndarray) -> tuple:
    """(magnitude, phase) worst errors of `results` against a complex truth per line."""
    s = np.array([ln.sensitivity_mv_per_ms2 for ln in results.lines])
    u = np.array([ln.expanded_uncertainty_mv_per_ms2 for ln in results.lines])
    phase = np.array([ln.phase_deg for ln in results.lines])
    u_phase = np.array([ln.phase_expanded_uncertainty_deg for ln in results.lines])
    phase_error = (phase - true_phase + 180) % 360 - 180
    magnitude = _worst(100 * (s - true_s) / true_s, 100 * u / true_s)
    return magnitude, _worst(phase_error, u_phase)


def sim_case(name: str, out: Path, dut: str, tolerance: float | None = None, seed: int = 1) -> Case:
    """A run on the simulated stand, checked against its recording's truth."""
    finished = execute(
        RunRequest(
            dut=dut,
            periods=8,
            seed=seed,
            tolerance_percent=tolerance,
            out=out,
            estimator=Estimator.PERIODIC,  # the table's protocol (lpm the default since issue 34)
        )
    )
    results = finished.results
    truth = read_recording(out / finished.record.run_id / "recording.h5").truth
    magnitude, phase = against_truth(results, truth.sensitivity_mv_per_ms2, truth.phase_deg)
    mounting = [w for w in results.warnings if w.startswith("mounting:")]
    note = "; ".join(mounting) or next(
        (r for r in results.verdict_reasons if "fail" in r or "inconclusive" in r), ""
    )
    return Case(name, magnitude, phase, str(results.verdict), note)


FLAT_MV = 10.0
SKEW_TOLERANCES = Tolerances(
    nominal_sensitivity_mv_per_ms2=FLAT_MV,
    sensitivity_percent=5.0,
    characteristic=(Band(0.0, 5000.0, 5.0),),
    phase=(Band(0.0, 5000.0, 1.0),),
    source="flat DUT, +-1 deg phase",
)


def skew_case(name: str, skew_s: float, told: float | None) -> Case:
    """A synthetic recording of a flat DUT sampled `skew_s` late, analysed knowing `told`."""
    plan = preset_plan("piezo", optimiser=stored_phases)
    budget = Budget(
        (
            Component("reference calibration", 0.005, Distribution.NORMAL),
            Component("phase match", 0.1, Distribution.RECTANGULAR, quantity=Quantity.PHASE),
        )
    )
    recording: Recording = make_recording(
        plan,
        lambda f: np.full(np.shape(f), FLAT_MV, dtype=complex),
        periods=8,
        reference_noise_v=5e-6,
        dut_noise_v=5e-5,
        skew_s=skew_s,
        seed=5,
        budget=budget,
    )
    recording = dataclasses.replace(recording, chain=ReferenceChain.flat(1.0, skew_s=told))
    results = analyze(recording, tolerances=SKEW_TOLERANCES).results
    true_s = np.full(len(plan.lines), FLAT_MV)
    magnitude, phase = against_truth(results, true_s, np.zeros(len(plan.lines)))
    note = (
        "phase corrected for the delay"
        if results.phase_corrected_for_skew
        else "phase flagged: not corrected for skew, not stated"
    )
    return Case(name, magnitude, phase, str(results.verdict), note)


def table(cases: list[Case]) -> str:
    head = (
        "| case | magnitude error (U there) | max abs(e)/U | phase error (U there) | "
        "max abs(e)/U | verdict | note |\n| --- | --- | --- | --- | --- | --- | --- |"
    )
    rows = [
        f"| {c.name} | {c.magnitude[0]:.3f} % ({c.magnitude[1]:.2f} %) | {c.magnitude[2]:.2f} | "
        f"{c.phase[0]:.3f}° ({c.phase[1]:.2f}°) | {c.phase[2]:.2f} | {c.verdict} | {c.note} |"
        for c in cases
    ]
    return "\n".join([head, *rows])


def main() -> int:
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    smoke = "--smoke" in sys.argv[1:]  # one case of each kind: checks it still runs
    cases = []
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        cases.append(sim_case("clean: piezo, 5 m/s², L = 8", out, "piezo"))
        if smoke:
            cases.append(skew_case("skew +2 µs, --skew given", 2e-6, 2e-6))
            print(table(cases))
            return 0
        cases.append(sim_case("noisy: capacitive MEMS, 200 µg/√Hz", out, "capacitive"))
        cases.append(
            sim_case("straddling: piezo against a ±0.5 % characteristic", out, "piezo", 0.5)
        )
        cases.append(sim_case("out of tolerance: capacitive against ±5 %", out, "capacitive", 5.0))
        cases.append(sim_case("loose mount (resonance 1.2 kHz)", out, "loose"))
    for sign in (+1, -1):
        skew = sign * 2e-6
        cases.append(skew_case(f"skew {skew * 1e6:+g} µs, --skew given", skew, skew))
        cases.append(skew_case(f"skew {skew * 1e6:+g} µs, no skew given", skew, None))
    log.info("known-answer cases")
    print(table(cases))  # the product of this script: the table for docs/validation.md
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
