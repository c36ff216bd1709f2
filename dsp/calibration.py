"""From per-line estimates to the one results object (SPEC.md sections 2, 6, 7 and 8).

S_dut(f) = H(f) S_ref(f) G_ref / G_dut (SPEC s.2), in mV/(m/s^2), with S_ref(f) the reference
chain's complex sensitivity interpolated from its certificate; phase
phi_dut = arg H + phi_ref - 2 pi f tau (SPEC s.6), tau the DUT channel's sampling delay after
the reference channel (positive when the DUT channel is sampled later; unknown: the phase is
not corrected, flagged and not stated). Uncertainty per line: type A from the estimator,
type B from the budget, combined, Welch-Satterthwaite and k per SPEC s.7 (dsp.uncertainty); a
statement that needs U (ISO limit, tolerance) is "not stated" where U is 0 or undefined. The
results object is plain data: JSON-ready dicts and CSV text; files are written by the
application.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from dsp import conformity, nonlinear
from dsp import uncertainty as unc
from dsp.annex_a import incomplete_budget_text, missing_components
from dsp.budget_terms import reference_range
from dsp.characteristic import deviation_floor_percent, ratio_uncertainty
from dsp.cmc import Cmc, bound_line, scope_warnings
from dsp.conformity import NOT_STATED as NOT_STATED  # re-exported for its callers
from dsp.conformity import uncertainty_stated as uncertainty_stated
from dsp.errors import InputRefused
from dsp.multisine import Plan
from dsp.not_stated import not_stated_line as not_stated_line  # re-exported for its callers
from dsp.not_stated import read_back_not_stated, unresolved_lines
from dsp.quantiles import median  # np.median imports numpy.ma (issue 34)
from dsp.resonance import search_response
from dsp.result_values import _db, _fmt, _json_safe, _nan, _wrap_deg
from dsp.spectral import MIN_PERIODS, Estimate

RESULTS_FORMAT_VERSION = 1
LOW_COHERENCE = 0.99  # warn below this magnitude-squared coherence
LOW_SNR_DB = 20.0  # warn when a channel's per-period SNR at a line is lower
DEAD_SNR_DB = 6.0  # a channel whose median line SNR is below this is dead / not connected
DUT_DISTORTION_LIMIT = 0.01  # warn when the DUT adds more than 1 % harmonic distortion


class AnalysisError(InputRefused):
    """The data cannot give a calibration result (dead channel, no periods, ...)."""


@dataclass(frozen=True)
class ReferenceChain:
    """The reference accelerometer's certificate data and the gains of both chains.

    Sensitivity magnitude in mV/(m/s^2) and phase in degrees at certificate frequencies in Hz,
    interpolated linearly over log frequency and held constant beyond the end points. Gains are
    the conditioning amplifiers' V/V; `skew_s` is the DUT channel's sampling delay after the
    reference channel in s (multiplexed boards; positive when the DUT channel is sampled after
    the reference), None when unknown: the phase is then not corrected and not stated.
    """

    frequencies_hz: tuple[float, ...] = (160.0,)
    sensitivity_mv_per_ms2: tuple[float, ...] = (1.0,)
    phase_deg: tuple[float, ...] = (0.0,)
    reference_gain: float = 1.0
    dut_gain: float = 1.0
    skew_s: float | None = 0.0

    def __post_init__(self) -> None:
        n = len(self.frequencies_hz)
        if n == 0 or len(self.sensitivity_mv_per_ms2) != n or len(self.phase_deg) != n:
            raise ValueError(
                "reference chain: frequencies_hz, sensitivity_mv_per_ms2 and phase_deg need "
                "the same, non-zero number of values"
            )
        f = np.asarray(self.frequencies_hz, dtype=float)
        if not np.all(np.isfinite(f) & (f > 0)) or np.any(np.diff(f) <= 0):
            raise ValueError("reference chain: frequencies_hz must be positive and increasing")
        s = np.asarray(self.sensitivity_mv_per_ms2, dtype=float)
        if not np.all(np.isfinite(s) & (s > 0)):
            raise ValueError("reference chain: sensitivity_mv_per_ms2 must be positive")
        if not np.all(np.isfinite(self.phase_deg)):
            raise ValueError("reference chain: phase_deg must be finite")
        for name in ("reference_gain", "dut_gain"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"reference chain: {name} must be > 0, got {value!r}")
        if self.skew_s is not None and not math.isfinite(self.skew_s):
            raise ValueError("reference chain: skew_s must be finite (or None: unknown)")

    @classmethod
    def flat(cls, sensitivity_mv_per_ms2: float, **kwargs: Any) -> ReferenceChain:
        """A reference with one frequency-independent sensitivity and zero phase."""
        return cls((160.0,), (float(sensitivity_mv_per_ms2),), (0.0,), **kwargs)

    def sensitivity_at(self, frequency_hz: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Reference sensitivity (mV/(m/s^2)) and phase (deg) at frequencies in Hz."""
        log_f = np.log(np.asarray(self.frequencies_hz, dtype=float))
        x = np.log(np.asarray(frequency_hz, dtype=float))
        magnitude = np.interp(x, log_f, np.asarray(self.sensitivity_mv_per_ms2, dtype=float))
        phase = np.interp(x, log_f, np.asarray(self.phase_deg, dtype=float))
        return magnitude, phase

    def covers(self, frequency_hz: float) -> bool:
        """True when `frequency_hz` lies within the certificate's frequency range."""
        return self.frequencies_hz[0] <= frequency_hz <= self.frequencies_hz[-1] or (
            len(self.frequencies_hz) == 1
        )

    def to_dict(self) -> dict[str, Any]:
        return {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self).items()}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> ReferenceChain:
        """Rebuild from `to_dict`; ValueError naming the field on bad input."""
        known = {f for f in cls.__dataclass_fields__}
        unknown = set(data) - known
        if unknown:
            raise ValueError(f"reference chain: unknown field(s) {', '.join(sorted(unknown))}")
        kwargs: dict[str, Any] = {}
        for key, value in data.items():
            try:
                if key in ("frequencies_hz", "sensitivity_mv_per_ms2", "phase_deg"):
                    kwargs[key] = tuple(float(v) for v in value)
                elif key == "skew_s" and value is None:
                    kwargs[key] = None
                else:
                    kwargs[key] = float(value)
            except (TypeError, ValueError):
                raise ValueError(f"reference chain: field {key!r} is malformed") from None
        return cls(**kwargs)


@dataclass(frozen=True)
class LineResult:
    """Result at one line. Relative values are fractions (0.01 = 1 %), dB re 1 mV/(m/s^2)."""

    nominal_frequency_hz: float
    frequency_hz: float
    sensitivity_mv_per_ms2: float
    sensitivity_db: float
    deviation_percent: float
    deviation_db: float
    phase_deg: float
    relative_type_a: float
    relative_type_b: float
    relative_standard_uncertainty: float
    relative_expanded_uncertainty: float
    expanded_uncertainty_mv_per_ms2: float
    coverage_factor: float
    effective_dof: float
    phase_expanded_uncertainty_deg: float
    phase_coverage_factor: float
    coherence: float
    reference_snr_db: float
    dut_snr_db: float
    dut_distortion_percent: float
    iso_limit: float | None
    iso_verdict: str
    tolerance_verdict: str | None = None
    # U of deviation_percent, %, by dsp.characteristic's correlated model (common factors
    # cancel, the reference line's type A added); 0 at the reference line, whose deviation is
    # 0 by definition (issue 32 point 7); NaN in results stored before issue 25
    deviation_expanded_percent: float = math.nan
    # issue 32: the least U a conformity statement rests on (%, degrees: the CMC, else a full
    # budget's plausible floor; NaN: stored before) and what the CMC raised (dsp.cmc.bound_line)
    magnitude_floor_percent: float = math.nan
    phase_floor_deg: float = math.nan
    cmc_bounds: str = ""
    # why the line is not stated ("" when it is): outside the reference's calibrated range
    # with no extrapolation term (issue 32 point 5). Such a line carries no sensitivity,
    # deviation, phase or U (NaN, None in JSON, empty in CSV) and "not stated" verdicts.
    not_stated: str = ""

    @property
    def stated(self) -> bool:
        """True when the line's values are stated (see `not_stated`)."""
        return not self.not_stated


@dataclass(frozen=True)
class ReferenceResult:
    """Sensitivity at the reference frequency with its expanded uncertainty."""

    frequency_hz: float
    actual_frequency_hz: float
    sensitivity_mv_per_ms2: float
    sensitivity_db: float
    expanded_uncertainty_mv_per_ms2: float
    relative_expanded_uncertainty: float
    coverage_factor: float
    coverage_probability: float
    phase_deg: float
    phase_expanded_uncertainty_deg: float


@dataclass(frozen=True)
class Results:
    """The one results object: feeds the CLI, the GUI, the records and the certificate."""

    estimator: str
    periods: int
    sample_rate_hz: float
    period_samples: int
    coverage_probability: float
    uncertainty_rule: str
    reference: ReferenceResult
    lines: tuple[LineResult, ...]
    tolerance_percent: float | None = None
    warnings: tuple[str, ...] = field(default=())
    phase_corrected_for_skew: bool = True  # False: skew unknown, phase not stated
    verdict: str | None = None  # PASS, FAIL, INDETERMINATE (app.procedure.verdict); None: n/a
    verdict_reasons: tuple[str, ...] = field(default=())
    # ISO 16063-21 Annex A components the stand's budget does not state (dsp.annex_a); a run
    # with any is results for review only. Absent in results written before issue 25.
    missing_components: tuple[str, ...] = field(default=())
    # JCGM 101 validation per line and quantity (dsp.mcm.McmLine.to_dict), with --mcm only
    mcm: tuple[dict[str, Any], ...] = field(default=())
    # the laboratory's CMC the stated U was bounded by (dsp.cmc.Cmc.to_list); () none stated
    cmc: tuple[dict[str, float], ...] = field(default=())
    # the mounted-resonance search (dsp.resonance.ResonanceSearch.to_dict), when asked for
    resonance: dict[str, Any] | None = None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready nested dict (NaN and inf become None)."""
        data = asdict(self)
        data["format_version"] = RESULTS_FORMAT_VERSION
        data["lines"] = [asdict(line) for line in self.lines]
        data["warnings"] = list(self.warnings)
        data["verdict_reasons"] = list(self.verdict_reasons)
        data["missing_components"] = list(self.missing_components)
        data["mcm"] = [dict(m) for m in self.mcm]
        if not self.mcm:
            del data["mcm"]  # results without --mcm keep their pre-issue-25 shape
        data["cmc"] = [dict(b) for b in self.cmc]
        if self.resonance is None:
            del data["resonance"]  # and without a resonance search their pre-issue-32 shape
        return _json_safe(data)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Results:
        """Rebuild stored results (None back to NaN for numbers)."""
        try:
            reference = ReferenceResult(**_nan(data["reference"]))
            warnings = tuple(data.get("warnings", ()))
            lines = read_back_not_stated(
                tuple(LineResult(**_nan(item)) for item in data["lines"]),
                warnings,
                reference.frequency_hz,
            )
            return cls(
                estimator=data["estimator"],
                periods=int(data["periods"]),
                sample_rate_hz=float(data["sample_rate_hz"]),
                period_samples=int(data["period_samples"]),
                coverage_probability=float(data["coverage_probability"]),
                uncertainty_rule=data["uncertainty_rule"],
                reference=reference,
                lines=lines,
                tolerance_percent=data.get("tolerance_percent"),
                warnings=warnings,
                phase_corrected_for_skew=bool(data.get("phase_corrected_for_skew", True)),
                verdict=data.get("verdict"),
                verdict_reasons=tuple(data.get("verdict_reasons", ())),
                missing_components=tuple(str(m) for m in data.get("missing_components", ())),
                mcm=tuple(dict(m) for m in data.get("mcm", ())),
                cmc=tuple(dict(b) for b in data.get("cmc", ())),
                resonance=dict(data["resonance"]) if data.get("resonance") else None,
            )
        except (KeyError, TypeError) as exc:
            raise ValueError(f"results: missing or malformed field ({exc})") from None

    def to_csv(self) -> str:
        """One row per line, columns named with their units."""
        out = io.StringIO()
        names = list(LineResult.__dataclass_fields__)
        writer = csv.writer(out, lineterminator="\n")
        writer.writerow(names)
        for line in self.lines:
            writer.writerow(["" if v is None else _fmt(v) for v in asdict(line).values()])
        return out.getvalue()


def compute_results(
    estimate: Estimate,
    plan: Plan,
    chain: ReferenceChain,
    budget: unc.Budget,
    *,
    probability: float = 0.9545,
    rule: str = "gum",
    tolerance_percent: float | None = None,
    extra_warnings: Sequence[str] = (),
    cmc: Cmc | None = None,
    resonance: bool = False,
    transverse: bool = False,
) -> Results:
    """Sensitivity, characteristic, phase and uncertainty per line from an estimate.

    `tolerance_percent` is the DUT's permitted deviation of its characteristic from the
    reference sensitivity (e.g. the manufacturer's 5 %); verdicts use guarded acceptance.
    `cmc`: the laboratory's CMC, which no stated U is below (dsp.cmc.bound_line); a U below a
    line's floor gets no ISO or tolerance statement; no CMC blocks (issue 32 point 1).
    A line outside the reference's calibrated range without an extrapolation term is not
    stated (`not_stated_line`). `resonance`: search the mounted resonance in the response
    (`resonance_search`). Raises AnalysisError for a dead channel, or for a reference
    frequency outside the reference's calibrated range. `transverse`: the DUT channel is a
    triaxial sensor's cross axis (its signal the transverse one, small by design): exempt
    from the dead-channel refusal (the reference's still applies).
    """
    warnings = list(extra_warnings)
    labels = [f"{f:g} Hz" for f in plan.nominal_frequencies_hz]
    if estimate.nonlinear is not None:  # issue 32 point 4
        warnings.extend(nonlinear.warnings(estimate.nonlinear, labels, estimate.relative_type_a))
    for channel, snr in (("reference", estimate.reference_snr_db), ("DUT", estimate.dut_snr_db)):
        if transverse and channel == "DUT":
            continue
        alive = snr > DEAD_SNR_DB
        if not median(snr) > DEAD_SNR_DB:  # hum alone can light up a few lines
            raise AnalysisError(
                f"{channel} channel: no signal at most lines ({int(alive.sum())} of "
                f"{alive.size} above {DEAD_SNR_DB:g} dB SNR); check the cable, the IEPE supply "
                "and the channel assignment"
            )
    frequencies = plan.frequencies_hz
    s_ref, phi_ref = chain.sensitivity_at(frequencies)
    response = estimate.response
    sensitivity = np.abs(response) * s_ref * chain.reference_gain / chain.dut_gain
    skew_known = chain.skew_s is not None
    skew_s = chain.skew_s if chain.skew_s is not None else 0.0
    phase = _wrap_deg(np.degrees(np.angle(response)) + phi_ref - 360.0 * frequencies * skew_s)
    if not skew_known:
        warnings.append(
            "phase not corrected for skew: the inter-channel delay is unknown (give --skew or "
            "a '# skew_s = ...' header line); the phase characteristic is not stated"
        )
    ref_index = plan.reference_index
    s0 = sensitivity[ref_index]

    need = MIN_PERIODS.get(estimate.estimator, 2)
    if estimate.periods < 2 and need >= 2:
        warnings.append(f"one period only: no type A uncertainty; acquire at least {need} periods")
    elif estimate.periods < need:  # issue 13 point 5: no honest type A below the minimum
        warnings.append(
            f"{estimate.periods} periods: the {estimate.estimator} estimator states a type A "
            f"uncertainty from {need} periods on, so no uncertainty is stated; acquire at "
            f"least {need} periods"
        )
    # the procedure's own terms (hum) carry no Annex A kind: they never complete a budget
    missing = missing_components(budget)
    if not budget.components:
        warnings.append(
            "no type B budget: the stated uncertainty is type A only (reference calibration, "
            "gains, mounting... are not included); give the stand's budget"
        )
    elif missing:
        warnings.append(incomplete_budget_text(missing))
    warnings.extend(scope_warnings(cmc, plan.nominal_frequencies_hz, budget))  # issue 32
    refused = [False] * len(labels)
    if len(chain.frequencies_hz) > 1:  # a one-point (flat) reference is stated everywhere
        span = reference_range(frequencies.tolist(), chain.frequencies_hz, budget)
        warnings.extend(span.messages(list(plan.nominal_frequencies_hz), *_span(chain)))
        refused = list(span.refused)
        if refused[ref_index]:
            lo, hi = _span(chain)
            raise AnalysisError(
                f"reference frequency {plan.reference_frequency_hz:g} Hz (played at "
                f"{frequencies[ref_index]:g} Hz): outside the reference certificate "
                f"({lo:g}-{hi:g} Hz), so no line can be stated; choose a reference frequency "
                "inside it"
            )
    unresolved = unresolved_lines(warnings)  # too few LSB: not stated (issue 32 point 2)
    lines = []
    dofs = np.broadcast_to(np.asarray(estimate.dof, dtype=float), (len(labels),))
    f0 = float(frequencies[ref_index])
    for k, label in enumerate(labels):
        f = float(frequencies[k])
        dof = float(dofs[k])
        mag = unc.combine(
            float(estimate.relative_type_a[k]),
            dof,
            budget,
            f,
            unc.Quantity.MAGNITUDE,
            probability=probability,
            rule=rule,
            periods=estimate.periods,
        )
        ph = unc.combine(
            math.degrees(float(estimate.phase_type_a_rad[k])),
            dof,
            budget,
            f,
            unc.Quantity.PHASE,
            probability=probability,
            rule=rule,
            periods=estimate.periods,
        )
        deviation = sensitivity[k] / s0 - 1.0
        if k == ref_index:  # dev = 0 by definition, with no uncertainty (issue 32 point 7)
            u_deviation = 0.0
        else:
            ratio = ratio_uncertainty(
                float(estimate.relative_type_a[k]),
                dof,
                float(estimate.relative_type_a[ref_index]),
                float(dofs[ref_index]),
                budget,
                f,
                f0,
                probability=probability,
                rule=rule,
                periods=estimate.periods,
            )
            u_deviation = 100.0 * (1.0 + float(deviation)) * ratio.expanded
        b = bound_line(cmc, plan.nominal_frequencies_hz[k], mag.expanded, ph.expanded,
                       u_deviation, float(deviation))  # ILAC P14, issue 32  # fmt: skip
        u_mag, u_deviation, mag_floor = b.magnitude, b.deviation_percent, b.magnitude_floor
        verdict: str = unc.iso_verdict(f, u_mag)
        if verdict != unc.Verdict.NOT_APPLICABLE and not uncertainty_stated(u_mag, mag_floor):
            verdict = NOT_STATED  # no U, or one below the floor: neither within nor over
        tolerance = (
            None
            if tolerance_percent is None or k == ref_index  # the reference line: 0 by definition
            else conformity.decide(  # looked up here: one function, a test can replace it
                100 * deviation,
                u_deviation,
                tolerance_percent,
                deviation_floor_percent(100 * float(deviation), 100 * mag_floor),
            )
        )
        lines.append(
            LineResult(
                nominal_frequency_hz=float(plan.nominal_frequencies_hz[k]),
                frequency_hz=f,
                sensitivity_mv_per_ms2=float(sensitivity[k]),
                sensitivity_db=_db(float(sensitivity[k])),
                deviation_percent=100.0 * float(deviation),
                deviation_db=20.0 * math.log10(sensitivity[k] / s0),
                phase_deg=float(phase[k]),
                relative_type_a=float(estimate.relative_type_a[k]),
                relative_type_b=mag.type_b,
                relative_standard_uncertainty=mag.standard,
                relative_expanded_uncertainty=u_mag,
                expanded_uncertainty_mv_per_ms2=float(u_mag * sensitivity[k]),
                coverage_factor=mag.coverage_factor,
                effective_dof=mag.dof,
                phase_expanded_uncertainty_deg=b.phase_deg,
                phase_coverage_factor=ph.coverage_factor,
                coherence=float(estimate.coherence[k]),
                reference_snr_db=float(estimate.reference_snr_db[k]),
                dut_snr_db=float(estimate.dut_snr_db[k]),
                dut_distortion_percent=100.0 * float(estimate.dut_distortion[k]),
                iso_limit=unc.iso_16063_21_limit(f),
                iso_verdict=str(verdict),
                tolerance_verdict=tolerance,
                deviation_expanded_percent=u_deviation,
                magnitude_floor_percent=100 * mag_floor,
                phase_floor_deg=b.phase_floor_deg,
                cmc_bounds=b.bounds,
            )
        )
        if refused[k]:
            lines[-1] = not_stated_line(lines[-1], _outside_text(chain))
        elif k != ref_index and (
            reason := unresolved.get(f"{f:g}") or unresolved.get(label.removesuffix(" Hz"))
        ):
            lines[-1] = not_stated_line(lines[-1], reason)  # too few LSB (issue 32 point 2)
        warnings.extend(_line_warnings(label, estimate, k, chain, f))
    r = lines[ref_index]
    reference = ReferenceResult(
        frequency_hz=r.nominal_frequency_hz,
        actual_frequency_hz=r.frequency_hz,
        sensitivity_mv_per_ms2=r.sensitivity_mv_per_ms2,
        sensitivity_db=r.sensitivity_db,
        expanded_uncertainty_mv_per_ms2=r.expanded_uncertainty_mv_per_ms2,
        relative_expanded_uncertainty=r.relative_expanded_uncertainty,
        coverage_factor=r.coverage_factor,
        coverage_probability=(
            unc.seed_coverage_probability(estimate.periods) if rule == "seed" else probability
        ),
        phase_deg=r.phase_deg,
        phase_expanded_uncertainty_deg=r.phase_expanded_uncertainty_deg,
    )
    return Results(
        estimator=estimate.estimator,
        periods=estimate.periods,
        sample_rate_hz=plan.sample_rate_hz,
        period_samples=plan.period_samples,
        coverage_probability=reference.coverage_probability,
        uncertainty_rule=rule,
        reference=reference,
        lines=tuple(lines),
        tolerance_percent=tolerance_percent,
        warnings=tuple(warnings),
        phase_corrected_for_skew=skew_known,
        missing_components=tuple(missing),
        cmc=tuple(cmc.to_list()) if cmc is not None else (),
        resonance=(
            search_response(
                frequencies,
                sensitivity * np.exp(1j * np.radians(phase)),  # mV/(m/s^2), complex
                np.nan_to_num(np.asarray(estimate.relative_type_a, dtype=float), nan=0.0),
                mid_band_hz=f0,
                calibrated_hz=_span(chain) if len(chain.frequencies_hz) > 1 else None,
            ).to_dict()
            if resonance
            else None
        ),
    )


def _outside_text(chain: ReferenceChain) -> str:
    lo, hi = _span(chain)
    return f"outside the reference's calibrated range ({lo:g}-{hi:g} Hz)"


def _span(chain: ReferenceChain) -> tuple[float, float]:
    """The reference certificate's frequency range (Hz)."""
    return chain.frequencies_hz[0], chain.frequencies_hz[-1]


def _line_warnings(
    label: str, estimate: Estimate, k: int, chain: ReferenceChain, frequency_hz: float
) -> list[str]:
    out = []
    if estimate.periods >= 2 and estimate.coherence[k] < LOW_COHERENCE:
        out.append(f"line {label}: low coherence {estimate.coherence[k]:.3f}")
    for channel, snr in (
        ("reference", estimate.reference_snr_db[k]),
        ("DUT", estimate.dut_snr_db[k]),
    ):
        if snr < LOW_SNR_DB:
            out.append(f"line {label}: {channel} SNR {snr:.1f} dB is below {LOW_SNR_DB:g} dB")
    dut_d = estimate.dut_distortion[k]
    ref_d = estimate.reference_distortion[k]
    if np.isfinite(dut_d) and dut_d > DUT_DISTORTION_LIMIT and dut_d > 3 * np.nan_to_num(ref_d):
        out.append(
            f"line {label}: the DUT adds {100 * dut_d:.1f} % harmonic distortion "
            f"(reference {100 * ref_d:.1f} %)"
        )
    return out
