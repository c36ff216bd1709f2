"""Offline analysis of a recording: the same accumulator and results code as a live run."""

from __future__ import annotations

from dataclasses import dataclass

from app.recording import Recording, RecordingError, iter_batches
from dsp.calibration import Results, compute_results
from dsp.segments import segment_line_spectra, segment_plan
from dsp.spectral import Estimate, SpectralAccumulator


@dataclass(frozen=True)
class Analysis:
    """An analysed recording: the final estimate and the results built from it."""

    estimate: Estimate
    results: Results


def analyze(
    recording: Recording,
    *,
    estimator: str = "periodic",
    segments: int | None = None,
    probability: float = 0.9545,
    rule: str = "gum",
    tolerance_percent: float | None = None,
) -> Analysis:
    """Analyse whole periods (default) or, with `segments`, the seed's L equal segments."""
    plan = recording.plan
    warnings: list[str] = []
    if recording.periods <= recording.settle_periods or recording.acquired_periods == 0:
        raise RecordingError(
            f"{recording.source}: {recording.periods} period(s) recorded, none left after "
            f"{recording.settle_periods} settle period(s)"
        )
    if segments is None:
        accumulator = SpectralAccumulator(plan.period_samples, plan.bins)
        for reference, dut in iter_batches(recording):
            accumulator.add_periods(reference, dut)
    else:
        start = recording.settle_periods * recording.period_samples
        reference = recording.reference_v[start:]
        dut = recording.dut_v[start:]
        labels = [f"{f:g} Hz" for f in plan.nominal_frequencies_hz]
        length, warnings = segment_plan(
            reference.size, segments, plan.frequencies_hz, labels, plan.sample_rate_hz
        )
        accumulator = SpectralAccumulator(length, plan.bins, track_floor=False)
        spectra = [
            segment_line_spectra(x, segments, length, plan.frequencies_hz, plan.sample_rate_hz)
            for x in (reference, dut)
        ]
        accumulator.add_line_spectra(*spectra)
    estimate = accumulator.estimate(estimator)
    results = compute_results(
        estimate,
        plan,
        recording.chain,
        recording.budget,
        probability=probability,
        rule=rule,
        tolerance_percent=tolerance_percent,
        extra_warnings=warnings,
    )
    return Analysis(estimate, results)
