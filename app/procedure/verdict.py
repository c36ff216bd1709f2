"""The overall verdict of a run: PASS, FAIL or INDETERMINATE, with its reasons.

One place computes it; the procedure and the offline analysis call `with_verdict`, the CLI,
the GUI and the certificate only read `Results.verdict` and `Results.verdict_reasons`.

Decision rule: dsp.conformity.decide, the one ILAC-G8 guarded acceptance (its wording there
too); a deviation's U is dsp.characteristic's correlated model. Checks, against the DUT
model's tolerances:
sensitivity at the reference frequency against its nominal value, the amplitude characteristic
per band (deviation from the reference frequency's sensitivity, %), and the phase per band
(|phase|, degrees). Overall: FAIL when any check fails; PASS when every check passes and
nothing else stands in the way; otherwise INDETERMINATE (an inconclusive or unstated check, no
tolerance at all, a mounting warning, a recording that did not complete, or any warning that
app.records.warnings says blocks PASS: an incomplete budget (ISO 16063-21 Annex A), low
coherence or SNR, DUT distortion, inseparable hum, a line over the ISO limit, a reference line
outside its certificate, the seed rule, an uncorrected skew).

Mounting check: a resonance inside the calibrated range (an interior line whose sensitivity
exceeds both neighbours' and the reference frequency's by more than RESONANCE_RISE, all three
stated: a peak the stated lines do not bracket blames no mount), or a
coherence drop that noise cannot explain (coherence below LOW_COHERENCE at a line where both
channels' SNR is at least CLEAN_SNR_DB), is a named warning ("mounting: ..."); with one the
verdict is never PASS.
"""

from __future__ import annotations

import dataclasses

from app.io.vocabulary import RunStatus
from app.records.warnings import RunWarning, WarningKind, blocking, iso_over_warning, printed
from app.stand.dut import Band, Tolerances
from dsp import conformity
from dsp import uncertainty as unc
from dsp.calibration import LOW_COHERENCE, LineResult, Results
from dsp.characteristic import (
    deviation_expanded_percent,
    deviation_floor_percent,
    line_deviation_expanded_percent,
)
from dsp.conformity import NOT_STATED, Outcome, Verdict
from dsp.conformity import decide as decide  # the one ILAC-G8 function (dsp.conformity)

PASS, FAIL, INDETERMINATE = Verdict.PASS, Verdict.FAIL, Verdict.INDETERMINATE
RESONANCE_RISE = 0.25  # an interior peak more than +25 % (about 2 dB) above the reference
CLEAN_SNR_DB = 40.0  # above this SNR on both channels, noise cannot explain a coherence drop
MOUNTING_PREFIX = "mounting: "
__all__ = [
    "CLEAN_SNR_DB",
    "FAIL",
    "INDETERMINATE",
    "MOUNTING_PREFIX",
    "PASS",
    "RESONANCE_RISE",
    "Band",
    "Tolerances",
    "assess",
    "decide",
    "iso_over_warnings",
    "mounting_warnings",
    "run_warnings",
    "tolerances_for",
    "with_verdict",
]


def tolerances_for(
    catalogue: str | None,
    reference_frequency_hz: float,
    tolerance_percent: float | None = None,
) -> Tolerances:
    """The tolerances of a simulated catalogue DUT (None: none known), with `tolerance_percent`
    (the --tolerance option) replacing the characteristic's bands by one over every line (a
    recording's truth names its DUT; a run carries its DutSpec instead)."""
    from app.stand.simulated import catalogue_spec

    spec = catalogue_spec(catalogue).with_options(tolerance_percent=tolerance_percent or None)
    return spec.tolerances(reference_frequency_hz)


def mounting_warnings(results: Results) -> list[str]:
    """Named warnings for a resonance or an unexplained coherence drop inside the calibrated
    range (see the module's docstring)."""
    lines = results.lines
    s0 = results.reference.sensitivity_mv_per_ms2
    out = []
    for k in range(1, len(lines) - 1):
        if not all(ln.stated for ln in lines[k - 1 : k + 2]):
            continue  # a peak beside a line not stated is not bracketed: no mount blamed
        s = lines[k].sensitivity_mv_per_ms2
        rise = s / s0 - 1.0
        if (
            s > lines[k - 1].sensitivity_mv_per_ms2
            and s > lines[k + 1].sensitivity_mv_per_ms2
            and rise > RESONANCE_RISE
        ):
            out.append(
                f"{MOUNTING_PREFIX}a resonance near {lines[k].nominal_frequency_hz:g} Hz inside "
                f"the calibrated range ({100 * rise:+.0f} % there): check the mounting (stud "
                "torque, contact surface, cable clamping)"
            )
    for ln in lines:
        clean = min(ln.reference_snr_db, ln.dut_snr_db) >= CLEAN_SNR_DB
        if results.periods >= 2 and clean and ln.coherence < LOW_COHERENCE:
            out.append(
                f"{MOUNTING_PREFIX}coherence {ln.coherence:.3f} at {ln.nominal_frequency_hz:g} "
                f"Hz with both channels above {CLEAN_SNR_DB:g} dB SNR: a rattling or loose "
                "mount; check the mounting"
            )
    return out


def iso_over_warnings(results: Results) -> list[RunWarning]:
    """The blocking warning of every line whose U is over the ISO 16063-21 limit."""
    return [
        iso_over_warning(ln.nominal_frequency_hz, ln.relative_expanded_uncertainty, ln.iso_limit)
        for ln in results.lines
        if ln.iso_verdict == unc.Verdict.OVER and ln.iso_limit is not None
    ]


def run_warnings(results: Results) -> list[str]:
    """The run's warnings with the ISO-over warning of each line, each text once."""
    texts = [*results.warnings, *(w.text for w in iso_over_warnings(results))]
    return list(dict.fromkeys(texts))


def _summary(name: str, outcomes: list[tuple[str, str]]) -> tuple[str, str]:
    """The worst outcome of a check over lines and one reason naming the lines concerned."""
    parts = []
    for kind in (Outcome.FAIL, Outcome.INCONCLUSIVE, NOT_STATED):
        hit = [label for outcome, label in outcomes if outcome == kind]
        if len(hit) > 4:
            parts.append(f"{kind} at {len(hit)} lines ({hit[0]} to {hit[-1]})")
        elif hit:
            parts.append(f"{kind} at {', '.join(hit)}")
    if not parts:
        return Outcome.PASS, f"{name}: pass at all {len(outcomes)} line(s) checked"
    found = {outcome for outcome, _ in outcomes}
    worst = next(k for k in (Outcome.FAIL, Outcome.INCONCLUSIVE, NOT_STATED) if k in found)
    return worst, f"{name}: {'; '.join(parts)}"


def _reference_line(results: Results) -> LineResult:
    """The line at the reference frequency."""
    r = results.reference
    return next(ln for ln in results.lines if ln.nominal_frequency_hz == r.frequency_hz)


def assess(
    results: Results, tolerances: Tolerances, status: str | None = None
) -> tuple[str, list[str], list[str]]:
    """The verdict, its reasons and the mounting warnings of `results`; `status` is the
    recording's (a recording that did not complete is never PASS)."""
    reasons: list[str] = []
    outcomes: list[str] = []
    r = results.reference
    nominal = tolerances.nominal_sensitivity_mv_per_ms2
    if nominal is not None and tolerances.sensitivity_percent is not None:
        deviation = 100 * (r.sensitivity_mv_per_ms2 / nominal - 1)
        u_deviation = deviation_expanded_percent(deviation, r.relative_expanded_uncertainty)
        floor = deviation_floor_percent(deviation, _reference_line(results).magnitude_floor_percent)
        outcome = conformity.decide(deviation, u_deviation, tolerances.sensitivity_percent, floor)
        outcomes.append(outcome)
        reasons.append(
            f"sensitivity at {r.frequency_hz:g} Hz: {outcome} ({deviation:+.2f} % from the "
            f"nominal {nominal:.4g} mV/(m/s^2), U {u_deviation:.2f} %,"
            f" tolerance ±{tolerances.sensitivity_percent:g} %)"
        )
    else:
        reasons.append("sensitivity at the reference frequency: no tolerance given, not checked")
    for name, bands, unit in (
        ("amplitude characteristic", tolerances.characteristic, "%"),
        ("phase", tolerances.phase, "°"),
    ):
        checked: list[tuple[str, str]] = []
        for ln in results.lines:
            band = next((b for b in bands if b.covers(ln.frequency_hz)), None)
            if band is None or (unit == "%" and ln.nominal_frequency_hz == r.frequency_hz):
                continue  # the reference line's deviation is 0 by definition
            label = f"{ln.nominal_frequency_hz:g} Hz"
            if unit == "%":
                u = line_deviation_expanded_percent(ln)  # the correlated model
                # the CMC, or a full budget's plausible floor, on the deviation's scale
                floor = deviation_floor_percent(ln.deviation_percent, ln.magnitude_floor_percent)
                outcome = conformity.decide(ln.deviation_percent, u, band.tolerance, floor)
                checked.append((outcome, label))
            elif not results.phase_corrected_for_skew:
                checked.append((NOT_STATED, label))
            else:
                u, floor = ln.phase_expanded_uncertainty_deg, ln.phase_floor_deg
                checked.append((conformity.decide(ln.phase_deg, u, band.tolerance, floor), label))
        if not checked:
            reasons.append(f"{name}: no tolerance given, not checked")
            continue
        worst, reason = _summary(name, checked)
        outcomes.append(worst)
        limits = ", ".join(f"±{b.tolerance:g} {unit}" for b in bands)
        reasons.append(f"{reason} (tolerance {limits})")
    mounting = mounting_warnings(results)
    if Outcome.FAIL in outcomes:
        verdict = FAIL
    elif not outcomes:
        verdict = INDETERMINATE
        reasons.insert(0, "no tolerance is set for this DUT: conformity cannot be decided")
    elif any(o != Outcome.PASS for o in outcomes):
        verdict = INDETERMINATE
    else:
        verdict = PASS
    if mounting:
        reasons += mounting
        if verdict == PASS:
            verdict = INDETERMINATE
    blocked = [w for w in blocking(run_warnings(results)) if w.text not in mounting]
    if blocked:
        reasons += [f"blocks PASS ({w.kind.value}): {w.text}" for w in blocked]
        if verdict == PASS:
            verdict = INDETERMINATE
    if any(w.kind is WarningKind.TYPE_A_TARGET for w in printed(run_warnings(results))):
        # honest either way: the checks above used U with the type A measured, not the target
        reasons.append(
            "type A target not met (the warning names the lines): each line is stated with "
            "the type A measured and the checks above use the U it gives"
        )
    if status not in (None, RunStatus.COMPLETE):
        reasons.append(f"the recording is {status}: results for review only")
        if verdict == PASS:
            verdict = INDETERMINATE
    return verdict, reasons, mounting


def with_verdict(results: Results, tolerances: Tolerances, status: str | None = None) -> Results:
    """`results` with its verdict, reasons and mounting warnings (see `assess`)."""
    verdict, reasons, mounting = assess(results, tolerances, status)
    added = [*mounting, *(w.text for w in iso_over_warnings(results))]
    warnings = (*results.warnings, *(w for w in added if w not in results.warnings))
    return dataclasses.replace(
        results, verdict=verdict, verdict_reasons=tuple(reasons), warnings=warnings
    )
