"""Offline analysis of a recording: the same accumulator and results code as a live run.

A recording carries how it ended (app.io.hdf5): results from an aborted or incomplete one
say so in their status and warnings and are never certified. A recording inside a run folder
is analysed only after the folder's manifest verifies (app.records.run_folder).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from app.io.hdf5 import Recording, RecordingError, iter_batches, read_recording
from app.io.vocabulary import RunStatus
from app.procedure.verdict import Tolerances, tolerances_for, with_verdict
from app.records.run_folder import FolderState, RunCheck, inspect_run, is_run_folder
from app.records.warnings import SEED_RULE_WARNING
from dsp.calibration import ReferenceChain, Results, compute_results
from dsp.hum import driven_hum_of_periods, mains_hum, merged
from dsp.lpm_record import (
    WHOLE_RECORD_PERIODS,
    hum_bins,
    record_estimate,
    record_estimate_batches,
)
from dsp.mcm import validate_lines
from dsp.multisine import Plan, PlanError
from dsp.segments import segment_line_spectra, segment_plan
from dsp.spectral import RECORD_ESTIMATORS, Estimate, SpectralAccumulator
from dsp.uncertainty import Budget, Quantity


@dataclass(frozen=True)
class Analysis:
    """An analysed recording: the final estimate and the results built from it."""

    estimate: Estimate
    results: Results
    status: RunStatus | None = None  # the recording's; None: CSV, in memory


#: The verdict reason of a triaxial sensor's cross channel (`transverse`): it carries none.
CROSS_CHANNEL_REASON = (
    "no verdict: a triaxial sensor's cross channel (not along the exciter) measures a "
    "transverse sensitivity, not its axis's main sensitivity; the triaxial certificate states "
    "it as a transverse sensitivity ratio with its U"
)


def analyze(
    recording: Recording,
    *,
    estimator: str = "periodic",
    segments: int | None = None,
    probability: float = 0.9545,
    rule: str = "gum",
    tolerance_percent: float | None = None,
    tolerances: Tolerances | None = None,
    mcm_trials: int | None = None,
    transverse: bool = False,
    resonance: bool = False,
) -> Analysis:
    """Analyse whole periods (default) or, with `segments`, the seed's L equal segments.

    The results carry the overall verdict (app.procedure.verdict) against `tolerances`; by
    default those of the simulated DUT the recording's truth names, else `tolerance_percent`
    alone. `rule="seed"` adds the blocking SEED_RULE_WARNING (k from t(L-1) is not GUM);
    `mcm_trials` validates every line's GUM interval by JCGM 101 Monte Carlo (`with_mcm`);
    `transverse`: a triaxial sensor's cross channel (no dead-channel refusal of the DUT's, no
    tolerance and no verdict: CROSS_CHANNEL_REASON); `resonance`: search the mounted
    resonance in the response (dsp.resonance; not on a cross channel)."""
    return analyze_chains(
        recording,
        [recording.chain],
        estimator=estimator,
        segments=segments,
        probability=probability,
        rule=rule,
        tolerance_percent=tolerance_percent,
        tolerances=tolerances,
        mcm_trials=mcm_trials,
        transverse=transverse,
        resonance=resonance,
    )[0]


def analyze_chains(
    recording: Recording,
    chains: Sequence[ReferenceChain],
    *,
    estimator: str = "periodic",
    segments: int | None = None,
    probability: float = 0.9545,
    rule: str = "gum",
    tolerance_percent: float | None = None,
    tolerances: Tolerances | None = None,
    mcm_trials: int | None = None,
    transverse: bool = False,
    resonance: bool = False,
) -> list[Analysis]:
    """As `analyze`, once per reference chain of `chains` (e.g. the stored and a corrected
    calibration table: app.procedure.impact): the recording is read and estimated once (the
    estimate and the hum do not depend on the chain), the results computed per chain; each
    equals `analyze` of the recording with that chain."""
    plan = recording.plan
    status_note = status_warning(recording.status)
    warnings: list[str] = [status_note] if status_note else []
    if recording.periods <= recording.settle_periods or recording.acquired_periods == 0:
        raise RecordingError(
            f"{recording.source}: {recording.periods} period(s) recorded, none left after "
            f"{recording.settle_periods} settle period(s)"
        )
    mean = PeriodMean()
    if estimator in RECORD_ESTIMATORS:  # lpm: the analysed periods as one record
        if segments is not None:
            raise RecordingError("--segments: the lpm estimator analyses whole periods")
        estimate = _record_estimate(recording, mean)
    elif segments is None:
        accumulator = SpectralAccumulator(
            plan.period_samples, plan.bins, nonlinear_excluded_bins=hum_bins(plan)
        )
        for reference, dut in iter_batches(recording):  # a stored recording: a batch in memory
            accumulator.add_periods(reference, dut)
            mean.add(reference, dut)
    else:
        start = recording.settle_periods * recording.period_samples
        reference = recording.reference_v[start:]
        dut = recording.dut_v[start:]
        labels = [f"{f:g} Hz" for f in plan.nominal_frequencies_hz]
        length, segment_warnings = segment_plan(
            reference.size, segments, plan.frequencies_hz, labels, plan.sample_rate_hz
        )
        warnings.extend(segment_warnings)
        accumulator = SpectralAccumulator(length, plan.bins, track_floor=False)
        spectra = [
            segment_line_spectra(x, segments, length, plan.frequencies_hz, plan.sample_rate_hz)
            for x in (reference, dut)
        ]
        accumulator.add_line_spectra(*spectra)
    if estimator not in RECORD_ESTIMATORS:
        estimate = accumulator.estimate(estimator)
    budget, hum_warnings = _budget_with_hum(recording, mean)
    warnings.extend(hum_warnings)
    warnings.extend(recording.resolution_warnings)  # the lines the run did not state
    if rule == "seed":
        warnings.append(SEED_RULE_WARNING)
    if tolerances is None:
        catalogue = recording.truth.attrs.get("dut") if recording.truth is not None else None
        tolerances = tolerances_for(
            str(catalogue) if catalogue else None, plan.reference_frequency_hz, tolerance_percent
        )
    out = []
    for chain in chains:
        results = compute_results(
            estimate,
            plan,
            chain,
            budget,
            probability=probability,
            rule=rule,
            tolerance_percent=None if transverse else tolerance_percent,
            extra_warnings=warnings,
            cmc=recording.cmc,
            resonance=resonance and not transverse,
            transverse=transverse,
        )
        if mcm_trials is not None:
            results = with_mcm(results, estimate, budget, probability, mcm_trials)
        if transverse:  # no tolerance applies to a transverse sensitivity
            results = dataclasses.replace(
                results, verdict=None, verdict_reasons=(CROSS_CHANNEL_REASON,)
            )
        else:
            results = with_verdict(results, tolerances, recording.status)
        out.append(Analysis(estimate, results, recording.status))
    return out


def _record_estimate(recording: Recording, mean: PeriodMean) -> Estimate:
    """The lpm estimate of the analysed periods as one record; with the recorded drive, that
    drive is checked to be periodic over it (a fade inside is refused). A record longer than
    WHOLE_RECORD_PERIODS is read a batch of periods at a time and held near its period grid
    (dsp.lpm_record.record_estimate_batches): memory independent of its length."""
    periods = recording.analysed_periods
    if periods > WHOLE_RECORD_PERIODS:
        return record_estimate_batches(_batches(recording, mean), periods, recording.plan).estimate
    reference, dut = recording.analysis_periods()
    mean.add(reference, dut)
    drive = None
    if recording.drive_v is not None:
        n = recording.period_samples
        start = recording.settle_periods * n
        drive = recording.drive_v[start : start + reference.size].reshape(reference.shape)
    return record_estimate(reference, dut, recording.plan, drive_blocks=drive).estimate


def _batches(
    recording: Recording, mean: PeriodMean
) -> Iterator[tuple[np.ndarray, np.ndarray, np.ndarray | None]]:
    """(reference, DUT, drive or None) of the analysed periods a batch at a time, each batch
    added to `mean` on the way (V)."""
    n = recording.period_samples
    start = recording.settle_periods * n
    for reference, dut in iter_batches(recording):
        mean.add(reference, dut)
        drive = None
        if recording.drive_v is not None:
            drive = np.asarray(recording.drive_v[start : start + reference.size], dtype=float)
            drive = drive.reshape(reference.shape)
        start += reference.size
        yield reference, dut, drive


class PeriodMean:
    """The mean analysed period of both channels, fed batch by batch (V): the periods are added
    one by one in order, as numpy's mean over the periods axis adds them, so a recording read in
    batches gives the mean of the whole array exactly (dsp.hum takes it as one period)."""

    def __init__(self) -> None:
        self.count = 0
        self._sums: list[np.ndarray] = []

    def add(self, reference: np.ndarray, dut: np.ndarray) -> None:
        """Add periods, arrays of shape (periods, N)."""
        for i in range(reference.shape[0]):
            if not self._sums:
                self._sums = [np.array(reference[i], dtype=float), np.array(dut[i], dtype=float)]
            else:
                self._sums[0] += reference[i]
                self._sums[1] += dut[i]
            self.count += 1

    def periods(self) -> tuple[np.ndarray, np.ndarray]:
        """The mean period of reference and DUT, each shape (1, N)."""
        if not self.count:
            raise ValueError("mean period: no period added")
        return (self._sums[0] / self.count)[None, :], (self._sums[1] / self.count)[None, :]


def with_mcm(
    results: Results, estimate: Estimate, budget: Budget, probability: float, trials: int
) -> Results:
    """`results` with the JCGM 101 validation of each line's magnitude and phase interval
    stored (dsp.mcm.McmLine.to_dict), and a printed warning per line that fails clause 8
    stating the Monte Carlo interval (% for magnitude, degrees for phase)."""
    if not 1000 <= trials <= 10_000_000:
        raise ValueError(f"--mcm: trials must be between 1000 and 10000000, got {trials}")
    frequencies = [ln.frequency_hz for ln in results.lines]
    dof = np.broadcast_to(np.asarray(estimate.dof, dtype=float), (len(frequencies),)).tolist()
    found = []
    for quantity, type_a in (
        (Quantity.MAGNITUDE, [ln.relative_type_a for ln in results.lines]),
        (
            Quantity.PHASE,
            [
                math.degrees(float(u)) if ln.stated else math.nan  # no statement to check
                for u, ln in zip(estimate.phase_type_a_rad, results.lines, strict=True)
            ],
        ),
    ):
        found += validate_lines(
            frequencies, type_a, dof, budget, quantity, probability=probability, trials=trials
        )
    warnings = [f"line {m.frequency_hz:g} Hz: {m.summary()}" for m in found if not m.validated]
    return dataclasses.replace(
        results,
        mcm=tuple(m.to_dict() for m in found),
        warnings=(*results.warnings, *warnings),
    )


def _budget_with_hum(recording: Recording, mean: PeriodMean) -> tuple[Budget, list[str]]:
    """The recording's budget with the hum this analysis measures, and a warning per line it
    reaches (issue 13 point 3, issue 32 point 3; dsp.hum): "mains hum at X Hz" (magnitude
    and phase) at every line on a mains harmonic, from the leading drive-off periods (drive
    exactly 0 V, among the settle periods) when the recording has a drive channel, else from
    the neighbouring mains harmonics (flagged as not separable from the line); and "hum while
    driven at X Hz" at every line a tone beside it reaches in the analysed periods. A
    component stored with the recording (measured at run time) is kept only when it is the
    larger: the budget carries the hum the warnings state."""
    if mean.count == 0:  # the estimator read the periods otherwise (segments): once more
        for reference, dut in iter_batches(recording):
            mean.add(reference, dut)
    periods = mean.periods()
    hum = mains_hum(recording.plan, periods, _drive_off_periods(recording))
    driven = driven_hum_of_periods(recording.plan, periods)
    components, warnings = [], []
    if hum.affected.any():
        components += hum.components()
        warnings += hum.warnings()
    if driven.affected.any():
        components += driven.components()
        warnings += driven.warnings()
    return merged(recording.budget, components), warnings


def _drive_off_periods(recording: Recording):
    """(reference, DUT) of the leading settle periods played at 0 V, or None."""
    if recording.drive_v is None:
        return None
    n = recording.period_samples
    count = 0
    while count < recording.settle_periods and (count + 1) * n <= recording.drive_v.size:
        if np.any(recording.drive_v[count * n : (count + 1) * n] != 0.0):
            break
        count += 1
    if count == 0:
        return None
    return (
        recording.reference_v[: count * n].reshape(count, n),
        recording.dut_v[: count * n].reshape(count, n),
    )


def reanalysis(
    recording: Recording,
    *,
    reference_frequency_hz: float | None = None,
    settle_periods: int | None = None,
    mains_frequency_hz: float | None = None,
) -> Recording:
    """A stored recording with re-analysis settings applied, each refused naming its option
    (RecordingError) when it cannot be: `reference_frequency_hz` must be a planned line (its
    nominal frequency); `settle_periods` more leading periods are dropped from the analysed
    ones when at least 2 remain; `mains_frequency_hz` replaces the plan's mains frequency (the
    mains-harmonic checks and hum logic use it)."""
    plan = recording.plan
    changes: dict[str, float] = {}
    if reference_frequency_hz is not None:
        if not any(
            math.isclose(f, reference_frequency_hz, rel_tol=1e-9)
            for f in plan.nominal_frequencies_hz
        ):
            raise RecordingError(
                f"--reference-frequency: {reference_frequency_hz:g} Hz is not a line of the "
                f"recording's plan ({', '.join(f'{f:g}' for f in plan.nominal_frequencies_hz)} Hz)"
            )
        changes["reference_frequency_hz"] = float(reference_frequency_hz)
    if mains_frequency_hz is not None:
        changes["mains_frequency_hz"] = float(mains_frequency_hz)
    if changes:
        try:
            plan = Plan.from_dict({**plan.to_dict(), **changes})
        except PlanError as exc:
            option = "--mains" if "mains_frequency_hz" in changes else "--reference-frequency"
            raise RecordingError(f"{option}: {exc}") from None
    settle = recording.settle_periods
    acquired = recording.acquired_periods
    if settle_periods is not None:
        if settle_periods < 0:
            raise RecordingError(f"--settle-periods: must be >= 0, got {settle_periods}")
        available = recording.analysed_periods
        if available - settle_periods < 2:
            raise RecordingError(
                f"--settle-periods: dropping {settle_periods} of the {available} analysed "
                "period(s) leaves fewer than 2 (type A needs them)"
            )
        settle += settle_periods
        acquired = None if acquired is None else acquired - settle_periods
    return dataclasses.replace(
        recording, plan=plan, settle_periods=settle, acquired_periods=acquired
    )


def status_warning(status: RunStatus | None) -> str | None:
    """The warning results of a recording with `status` carry (None for a complete one)."""
    if status == RunStatus.ABORTED:
        return "recording of an aborted run: results for review only, never certified"
    if status == RunStatus.INCOMPLETE:
        return (
            "incomplete recording (its run never finished, or it predates recording statuses): "
            "results for review only, never certified"
        )
    return None


RECORDING_NAME = "recording.h5"


def read_for_analysis(path: str | Path, *, check: RunCheck | None = None) -> Recording:
    """The HDF5 recording at `path`, a recording file or a run folder (its recording.h5). When
    it belongs to a run folder the folder is verified first (RecordingError naming the file
    with "hash mismatch" when it was changed) and the run's status joins the recording's;
    `check`: that folder's verification already made (app.records.run_folder.inspect_run),
    not repeated. The channels stay in the file, read a batch of periods at a time."""
    path = Path(path)
    folder, file = (path, path / RECORDING_NAME) if path.is_dir() else (path.parent, path)
    if not is_run_folder(folder):
        if path.is_dir():
            raise RecordingError(f"{path}: a folder but not a run folder (no manifest.json)")
        return read_recording(file, stored=True)
    run_status = _run_status(folder, check)
    if not file.exists():
        raise RecordingError(f"{file}: the run folder has no recording")
    recording = read_recording(file, stored=True)
    return dataclasses.replace(recording, status=_joined(run_status, recording.status))


def _run_status(folder: Path, check: RunCheck | None = None) -> RunStatus:
    """complete, aborted or incomplete (interrupted); RecordingError when it does not verify
    (`check`: its verification already made, else made here)."""
    if check is None or check.path.resolve() != folder.resolve():
        try:
            check = inspect_run(folder)
        except ValueError as exc:  # unreadable manifest, not a run folder
            raise RecordingError(str(exc)) from None
    if check.state in (FolderState.MODIFIED, FolderState.UNSUPPORTED):
        raise RecordingError("; ".join(check.problems))
    if check.state == FolderState.RUNNING:
        raise RecordingError(f"{folder}: the run is still being written; analyse it once it ends")
    if check.state == FolderState.INTERRUPTED:
        return RunStatus.INCOMPLETE
    return RunStatus(check.state)  # complete or aborted


def _joined(run_status: RunStatus, recording_status: RunStatus | None) -> RunStatus:
    """The verified run's status, unless the recording's own mark says aborted."""
    return RunStatus.ABORTED if recording_status == RunStatus.ABORTED else run_status
