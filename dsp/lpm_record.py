"""The LPM (dsp.lpm) on a run's analysed record: M whole periods of a plan, read after the
fade-in, as one record -> a dsp.spectral.Estimate for dsp.calibration (issue 26 point 3).

The record's DFT has M bins per period bin, so the lines sit at bins plan.bins * M and the
windows of non-excited bins lie between them; type A is the LPM's, with Student t at its
degrees of freedom per line (2 q real). The DUT's nonlinear distortion is measured at the
free (detection) bins of the record and carried to every line (dsp.nonlinear, issue 32 point
4): when found, the stated H is the best linear approximation at this excitation (the record's
stochastic nonlinear part removed, its estimate's uncertainty in type A, the LPM run on the
record with the fitted products taken out of its windows) and a printed warning says so; when
the model does not explain the products, a blocking warning names the lines they reach.
Coherence is not defined for one record (NaN);
distortion is the periodic content at the free 2nd..5th harmonic bins of each line, counted
where it stands clear of the local noise (exponential law of |X|^2 for noise alone, Sidak
over the bins tested, 1 % false alarm per run) and bias-corrected for it. Volts in, V/V out.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np

from dsp import lpm, nonlinear
from dsp.calibration import AnalysisError
from dsp.lpm_neighbours import NeighbourAccumulator
from dsp.multisine import Plan
from dsp.spectral import DISTORTION_FALSE_ALARM, HARMONICS, Estimate

ESTIMATOR = "lpm"
NOISE_HALF_WIDTH_BINS = 12  # local noise power around a harmonic bin, from non-excited bins
WHOLE_RECORD_PERIODS = 16  # the longest record analysed whole (the product's default: 1-16)
NEIGHBOURHOOD_BINS = 12  # a longer record is held within this many bins of each grid bin


@dataclass(frozen=True)
class RecordEstimate:
    """The estimate for dsp.calibration and the LPM's own result (transients, covariance,
    per-drive FRFs) of one record of `periods` periods."""

    estimate: Estimate
    lpm: lpm.LpmEstimate
    periods: int
    nonlinear: nonlinear.NonlinearEstimate | None = None


def record_estimate(
    reference_blocks: np.ndarray,
    dut_blocks: np.ndarray,
    plan: Plan,
    *,
    drive_blocks: np.ndarray | None = None,
    settings: lpm.LpmSettings | None = None,
) -> RecordEstimate:
    """LPM estimate of consecutive periods (rows of shape (M, N), volts) taken as one record.
    With `drive_blocks` (the drive as played, same shape) the drive is checked to be periodic
    over the record and the FRFs per drive volt are returned. AnalysisError names the cause."""
    ref = np.atleast_2d(np.asarray(reference_blocks, dtype=float))
    dut = np.atleast_2d(np.asarray(dut_blocks, dtype=float))
    n = plan.period_samples
    if ref.shape != dut.shape or ref.shape[1] != n or ref.shape[0] < 1:
        raise AnalysisError(
            f"lpm: expected whole periods of {n} samples for both channels, got "
            f"{ref.shape} and {dut.shape}"
        )
    periods = ref.shape[0]
    lines = plan.bins * periods
    excluded = hum_bins(plan, periods)
    drive = None if drive_blocks is None else np.asarray(drive_blocks, float).reshape(1, -1)

    def local_polynomial(dut_record: np.ndarray) -> lpm.LpmEstimate:
        """The LPM of the reference record and `dut_record` (V), this plan's lines and bins."""
        try:
            return lpm.estimate(
                ref.reshape(1, -1),
                dut_record.reshape(1, -1),
                lines,
                settings=settings,
                excluded_bins=excluded,
                drive_v=drive,
            )
        except lpm.LpmError as exc:
            raise AnalysisError(f"lpm: {exc}") from None

    result = local_polynomial(dut)
    y_spec = np.fft.rfft(dut.reshape(-1)) * (2.0 / (periods * n))
    u_spec = np.fft.rfft(ref.reshape(-1)) * (2.0 / (periods * n))
    assert result.reference_lines_v is not None
    reference_record = ref.reshape(-1)
    found = nonlinear.estimate(
        y_spec,
        u_spec,
        lines,
        result.reference_lines_v,
        result.response,
        reference_record,
        excluded_bins=excluded,
    )
    response = result.response
    magnitude_u, phase_u, dof = result.relative_type_a, result.phase_type_a_rad, result.dof
    if found.found:
        cleaned = nonlinear.cleaned(
            y_spec,
            found,
            result.reference_lines_v,
            lines,
            reference_record,
            excluded,
        )
        record = np.fft.irfft(cleaned, periods * n) * (periods * n / 2.0)
        result = local_polynomial(record)
        carried = nonlinear.carry(
            result.response, result.relative_type_a, result.phase_type_a_rad, result.dof, found
        )
        response, magnitude_u, phase_u = carried.response, carried.magnitude_u, carried.phase_u_rad
        dof = carried.dof
    per_period = math.sqrt(periods)  # record noise -> one period's (white noise), for the SNR
    estimate = Estimate(
        estimator=ESTIMATOR,
        periods=periods,
        response=response,
        relative_type_a=magnitude_u,
        phase_type_a_rad=phase_u,
        dof=np.asarray(dof, dtype=float),
        coherence=np.full(lines.size, np.nan),
        reference_amplitude_v=result.reference_amplitude_v,
        dut_amplitude_v=result.dut_amplitude_v,
        reference_noise_v=result.reference_noise_v * per_period,
        dut_noise_v=result.dut_noise_v * per_period,
        reference_distortion=harmonic_distortion(u_spec, lines),
        dut_distortion=harmonic_distortion(y_spec, lines),
        nonlinear=found,
    )
    return RecordEstimate(estimate, result, periods, found)


def record_estimate_batches(
    batches: Iterable[tuple[np.ndarray, np.ndarray, np.ndarray | None]],
    periods: int,
    plan: Plan,
    *,
    settings: lpm.LpmSettings | None = None,
) -> RecordEstimate:
    """`record_estimate` of a long record read a batch of periods at a time: `batches` yields
    (reference, DUT, drive or None) of consecutive periods, shape (periods, N), V, `periods`
    in all. The record's spectra are accumulated exactly, but held only within
    NEIGHBOURHOOD_BINS (at least the LPM's reach) of every period-grid bin (dsp.lpm
    NeighbourAccumulator): the LPM's windows, the lines, the harmonics' noise neighbourhoods and
    the drive check read the very bins `record_estimate` reads; the nonlinear fit (dsp.nonlinear
    estimate_neighbourhood) uses the free bins held, not every free bin of the record (for
    records of at most 2 NEIGHBOURHOOD_BINS + 1 periods that is every bin). Memory independent
    of `periods`. AnalysisError names the cause."""
    record = BatchedRecord(periods, plan, settings=settings)
    for reference, dut, drive in batches:
        record.add(reference, dut, drive)
    return record.estimate()


class BatchedRecord:
    """The record of `periods` periods of `plan` fed a batch of consecutive periods at a time
    (`add`), then estimated once (`estimate`): `record_estimate_batches` in two steps, so a
    live run can feed it as its periods arrive (dsp.lpm_live). The result depends on how the
    periods are cut into batches only through rounding; fed the batches `analyze` reads
    (app.io.hdf5.iter_batches: 16 periods) it is bit-identical. Memory independent of
    `periods`."""

    def __init__(
        self, periods: int, plan: Plan, *, settings: lpm.LpmSettings | None = None
    ) -> None:
        self.periods = int(periods)
        self.plan = plan
        self.settings = settings or lpm.LpmSettings()
        self._half_width = max(NEIGHBOURHOOD_BINS, self.settings.reach, NOISE_HALF_WIDTH_BINS)
        self._accumulator: NeighbourAccumulator | None = None
        self._moments = dict.fromkeys((4, 5, 6), 0.0)
        self._with_drive = False

    @property
    def added(self) -> int:
        """Periods added so far."""
        return 0 if self._accumulator is None else self._accumulator.added

    def add(self, reference: np.ndarray, dut: np.ndarray, drive: np.ndarray | None) -> None:
        """Add consecutive periods (shape (periods, N), V; the drive as played or recorded, or
        None for every batch). AnalysisError names a wrong shape or a drive given for some
        batches only."""
        n = self.plan.period_samples
        ref = np.atleast_2d(np.asarray(reference, dtype=float))
        if ref.shape[1:] != (n,) or np.shape(dut) != ref.shape:
            raise AnalysisError(
                f"lpm: expected whole periods of {n} samples for both channels, got "
                f"{ref.shape} and {np.shape(dut)}"
            )
        try:
            if self._accumulator is None:
                self._with_drive = drive is not None
                self._accumulator = NeighbourAccumulator(
                    self.periods, n, self._half_width, 6 + self._with_drive
                )
            if (drive is not None) != self._with_drive:
                raise AnalysisError("lpm: the drive is given for some periods and not others")
            # the powers made one at a time as the accumulator reaches them (memory)
            powers = [_power(ref, order) for order in nonlinear.ALL_ORDERS]
            extra = [] if drive is None else [np.asarray(drive, dtype=float)]
            self._accumulator.add(np.asarray(dut, dtype=float), ref, *powers, *extra)
        except lpm.LpmError as exc:
            raise AnalysisError(f"lpm: {exc}") from None
        for order in self._moments:
            self._moments[order] += float(np.sum(ref**order))

    def estimate(self) -> RecordEstimate:
        """The record's estimate, once every period is added (AnalysisError otherwise). The
        accumulated spectra are handed over: call it once."""
        accumulator = self._accumulator
        if accumulator is None or accumulator.added != self.periods:
            raise AnalysisError(f"lpm: {self.added} of {self.periods} periods read")
        self._accumulator = None
        return _estimate_of_spectra(
            accumulator, self._with_drive, self._moments, self.periods, self.plan, self.settings
        )


def _estimate_of_spectra(
    accumulator: NeighbourAccumulator,
    with_drive: bool,
    moments: dict[int, float],
    periods: int,
    plan: Plan,
    settings: lpm.LpmSettings,
) -> RecordEstimate:
    """The LPM and the nonlinear fit of a record whose spectra `accumulator` holds."""
    n = plan.period_samples
    y_spec, u_spec = accumulator.spectrum(0), accumulator.spectrum(1)
    powers_spec = {o: accumulator.spectrum(2 + i) for i, o in enumerate(nonlinear.ALL_ORDERS)}
    r_spec = accumulator.spectrum(6) if with_drive else None
    del accumulator
    lines = plan.bins * periods
    excluded = hum_bins(plan, periods)
    record_bins = periods * n // 2 + 1

    def local_polynomial(dut_spec: Any) -> lpm.LpmEstimate:
        try:
            return lpm.estimate_spectra(
                dut_spec,
                u_spec,
                lines,
                record_bins,
                settings=settings,
                excluded_bins=excluded,
                r_spec=r_spec,
            )
        except lpm.LpmError as exc:
            raise AnalysisError(f"lpm: {exc}") from None

    result = local_polynomial(y_spec)
    assert result.reference_lines_v is not None
    samples = periods * n
    found = nonlinear.estimate_neighbourhood(
        y_spec,
        u_spec,
        lines,
        result.reference_lines_v,
        result.response,
        powers_spec,
        {o: total / samples for o, total in moments.items()},
        excluded_bins=excluded,
    )
    response = result.response
    magnitude_u, phase_u, dof = result.relative_type_a, result.phase_type_a_rad, result.dof
    if found.found:
        cleaned = nonlinear.cleaned_neighbourhood(
            y_spec, found, result.reference_lines_v, lines, powers_spec, excluded
        )
        result = local_polynomial(cleaned)
        carried = nonlinear.carry(
            result.response, result.relative_type_a, result.phase_type_a_rad, result.dof, found
        )
        response, magnitude_u, phase_u = carried.response, carried.magnitude_u, carried.phase_u_rad
        dof = carried.dof
    per_period = math.sqrt(periods)
    estimate = Estimate(
        estimator=ESTIMATOR,
        periods=periods,
        response=response,
        relative_type_a=magnitude_u,
        phase_type_a_rad=phase_u,
        dof=np.asarray(dof, dtype=float),
        coherence=np.full(lines.size, np.nan),
        reference_amplitude_v=result.reference_amplitude_v,
        dut_amplitude_v=result.dut_amplitude_v,
        reference_noise_v=result.reference_noise_v * per_period,
        dut_noise_v=result.dut_noise_v * per_period,
        reference_distortion=harmonic_distortion(u_spec, lines),
        dut_distortion=harmonic_distortion(y_spec, lines),
        nonlinear=found,
    )
    return RecordEstimate(estimate, result, periods, found)


def _power(x: np.ndarray, order: int) -> Callable[[], np.ndarray]:
    """x**order, made when called."""
    return lambda: x**order


def hum_bins(plan: Plan, periods: int = 1) -> set[int]:
    """The bins of a record of `periods` periods of `plan` that hold mains hum (left out of the
    LPM's windows and of the detection bins of dsp.nonlinear)."""
    record_bins = periods * plan.period_samples // 2 + 1
    return lpm.mains_bins(
        plan.resolution_hz / periods, record_bins, plan.mains_frequency_hz, plan.mains_harmonics
    )


def harmonic_distortion(spectrum: Any, line_bins: np.ndarray) -> np.ndarray:
    """Per line, the rss of its periodic 2nd..5th harmonics relative to the line (a ratio),
    from one record's peak-scaled spectrum: a harmonic bin counts where |X|^2 exceeds
    t = ln(tests / alpha) times the local noise power (for noise alone |X|^2/s2 ~ Exp(1)),
    and its noise power is subtracted. Harmonics on a line, DC or beyond Nyquist are skipped."""
    size = spectrum.size
    line_set = {int(b) for b in line_bins}
    harmonics = [
        [h * int(k) for h in HARMONICS if h * int(k) < size - 1 and h * int(k) not in line_set]
        for k in line_bins
    ]
    blocked = line_set | {b for group in harmonics for b in group} | {0, size - 1}
    tests = max(sum(len(group) for group in harmonics), 1)
    threshold = math.log(tests / DISTORTION_FALSE_ALARM)
    power = np.abs(spectrum) ** 2 if isinstance(spectrum, np.ndarray) else _Power(spectrum)
    out = np.zeros(len(harmonics))
    for i, (k, group) in enumerate(zip(line_bins, harmonics, strict=True)):
        periodic = 0.0
        for b in group:
            near = [
                j
                for j in range(b - NOISE_HALF_WIDTH_BINS, b + NOISE_HALF_WIDTH_BINS + 1)
                if 0 < j < size - 1 and j not in blocked
            ]
            if not near:
                continue
            noise = float(np.mean(power[near]))
            if power[b] > threshold * noise:
                periodic += float(power[b]) - noise
        line_power = float(power[int(k)])
        out[i] = math.sqrt(periodic / line_power) if line_power > 0 else math.nan
    return out


class _Power:
    """|X|^2 per bin of a spectrum held near the period grid (lpm_neighbours.NeighbourSpectrum)."""

    def __init__(self, spectrum: Any) -> None:
        self._spectrum = spectrum

    def __getitem__(self, bins: Any) -> Any:
        return np.abs(self._spectrum[bins]) ** 2
