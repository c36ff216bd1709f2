"""Every sentence the certificate states (PDF and DCC), in one place; numbers come in already
printed (app.certificate.printed) or as the run stored them. The decision rule's own wording
is dsp.conformity's; here it is only placed into sentences.

Strings for the PDF may carry reportlab's paragraph mark-up (<b>); the DCC's carry none.
"""

from __future__ import annotations

from collections.abc import Sequence

from app.formatting import cmc_statement as cmc_statement  # one wording: CLI, PDF, DCC
from app.io.vocabulary import Mode
from app.records.run_record import RunRecord
from dsp import iso266
from dsp.calibration import Results
from dsp.conformity import DECISION_RULE, DECISION_RULE_SHORT, NOT_STATED, Outcome, Verdict

PHASE_NOT_STATED = "not stated (not corrected for the inter-channel delay)"
RELATE_ONLY = "The results relate only to the item calibrated."
FOOTER = (
    "The results relate only to the item calibrated. This certificate shall not be "
    "reproduced except in full without the laboratory's written approval."
)
VERDICT_RULE_NOTE = (
    f"Decision rule: {DECISION_RULE_SHORT}; INDETERMINATE where a result is inside its "
    "tolerance only without its uncertainty, where no uncertainty or tolerance is stated, or "
    "where the mounting is in doubt."
)
DCC_CONFORMITY: dict[str, str] = {
    Verdict.PASS: "pass",
    Verdict.FAIL: "fail",
}  # INDETERMINATE: in words only
CHARTS_NOTE = "Shaded: the expanded uncertainty (k as in the table)."
ADDRESS_NOT_STATED = "address not stated"  # the customer's, in the PDF and the DCC alike
PHASE_CONVENTION = (
    "Phase: the phase shift of the complex sensitivity (ISO 16063-1), the phase of the DUT's "
    "output voltage less the phase of the acceleration, phi = arg(S_dut); positive when the "
    "output leads the acceleration; the reference's certified phase and the inter-channel "
    "sampling delay are corrected for."
)
# technician's advice appended to a reason (app.procedure.verdict): for the bench, not for
# the customer; the certificate states the finding only
_ADVICE = (": check the mounting", "; check the mounting")
_VERDICT_WORDS: dict[str, str] = {  # the overall verdict (dsp.conformity.Verdict) in words
    Verdict.PASS: "the item <b>conforms</b> to its specification",
    Verdict.FAIL: "the item <b>does not conform</b> to its specification",
    Verdict.INDETERMINATE: (
        "INDETERMINATE, <b>conformity not stated</b>: a check is inconclusive or not stated, or "
        "the mounting is in doubt"
    ),
}


def method_text(record: RunRecord, results: Results) -> str:
    """The PDF's method paragraph: ISO 16063-21 comparison and the excitation of `record`."""
    plan = record.stored_plan
    freqs = list(plan.frequencies_hz)
    span = f"{min(freqs):g} Hz to {max(freqs):g} Hz" if freqs else ""
    series = (
        "ISO 266 one-third-octave values"
        if freqs and set(freqs) <= set(iso266.nominal_frequencies(min(freqs), max(freqs)))
        else "chosen frequencies"
    )
    excitation = (
        f"multisine excitation: {len(freqs)} frequencies at once ({series}, {span}), each "
        f"on a DFT bin of a {plan.period_s:g} s period sampled at "
        f"{plan.sample_rate_hz:g} Hz, phases optimised for a low crest factor, "
        "table acceleration equalised per frequency in closed loop"
        if record.mode == Mode.MULTISINE
        else f"stepped-sine excitation: {len(freqs)} frequencies one at a time ({span}), "
        "three-parameter sine fits (IEEE 1057)"
    )
    return (
        "Calibration by comparison with a reference transducer according to ISO 16063-21, "
        f"{excitation}. The sensitivity is the ratio of the DUT's and the reference's spectra "
        f"({results.estimator} estimator, {results.periods} periods averaged) times the reference "
        "chain's certified sensitivity, corrected for the conditioning gains and the DAQ's "
        f"inter-channel delay. Excitation time {record.excitation_time_s:.0f} s."
    )


def dcc_method_text(record: RunRecord, results: Results) -> str:
    """The DCC's usedMethod name."""
    plan = record.stored_plan
    lines = len(plan.frequencies_hz or results.lines)
    return (
        f"Back-to-back comparison with a reference accelerometer, multisine of {lines} lines, "
        f"{plan.sample_rate_hz:g} S/s, period of {plan.period_samples} "
        f"samples, {results.periods} periods, estimator {results.estimator}"
    )


def line_table_note(phase_stated: bool) -> str:
    """The note under the table of results per frequency."""
    return (
        "Deviation: sensitivity relative to the sensitivity at the reference frequency; at "
        "the reference frequency it is 0 by definition, and so is its U. U, U dev.: expanded "
        "uncertainty of the sensitivity and of the deviation (the characteristic), with the "
        "coverage factor k of its line. U vs. ISO 16063-21 limit: whether this calibration's "
        "relative expanded uncertainty is within the standard's suggested limits (2 % to 1 kHz, "
        "4 % to 2 kHz, 6 % to 10 kHz) or over them, a statement about the uncertainty of the "
        "calibration, not about the sensor (its conformity is the verdict, against the "
        "tolerances named there); n/s: not stated (no expanded uncertainty, or one below the "
        "laboratory's CMC or a full budget's plausible floor"
        + ("" if phase_stated else "; phase: " + PHASE_NOT_STATED)
        + ")."
    )


def uncertainty_statement(rule: str, p_percent: str) -> str:
    """How the expanded uncertainty was found: GUM with Welch-Satterthwaite, or the seed's."""
    if rule == "gum":
        return (
            "The reported expanded uncertainty of measurement is stated as the standard "
            "uncertainty of measurement multiplied by the coverage factor k, which for a "
            f"t-distribution with the effective degrees of freedom (Welch-Satterthwaite) "
            f"corresponds to a coverage probability of {p_percent}. It has been determined in "
            "accordance with JCGM 100:2008 (GUM) and ISO 16063-21."
        )
    return (
        "The expanded uncertainty uses the coverage factor rule of the method's source: "
        "Student's t at 95 % with L - 1 degrees of freedom for fewer than 10 periods, "
        "otherwise k = 2."
    )


def certificate_reason(reason: str) -> str:
    """A verdict reason as the certificate states it: the finding without the technician's
    advice (what to check at the bench stays in the CLI and the GUI)."""
    for advice in _ADVICE:
        if advice in reason:
            return reason[: reason.index(advice)]
    return reason


def conformity_statement(
    verdict: str | None, tolerance_percent: float | None, verdicts: Sequence[str | None]
) -> str:
    """The PDF's statement of conformity: the overall verdict's (every check: sensitivity,
    amplitude characteristic, phase, mounting) in words, with the characteristic's per-line
    outcomes (dsp.conformity's words: pass, fail, inconclusive, not stated)."""
    v = [x for x in verdicts if x is not None]  # None: the reference line, 0 by definition
    result = _VERDICT_WORDS.get(verdict or "", "<b>conformity not stated</b> (no verdict)")
    tally = (
        f" Amplitude characteristic within ±{tolerance_percent:g} % of the sensitivity at the "
        "reference frequency, at every other frequency (not stated: no U, or one below the "
        "laboratory's CMC or a full budget's plausible floor): "
        f"{v.count(Outcome.PASS)} pass, {v.count(Outcome.FAIL)} fail, "
        f"{v.count(Outcome.INCONCLUSIVE)} inconclusive, {v.count(NOT_STATED)} not stated of "
        f"{len(v)} frequencies."
        if tolerance_percent is not None
        else ""
    )
    return (
        "Against the DUT's tolerances (the checks under the overall verdict): "
        f"{result}. Decision rule: {DECISION_RULE}.{tally}"
    )


def dcc_declaration(verdict: str | None, reasons: Sequence[str]) -> str:
    """The DCC's statement of conformity: the overall verdict, the rule and the reasons."""
    joined = "; ".join(certificate_reason(r) for r in reasons)
    return f"Overall verdict: {verdict or 'not stated'}. Decision rule: {DECISION_RULE}." + (
        f" Reasons: {joined}." if joined else ""
    )


def dcc_conformity(verdict: str | None) -> str | None:
    """The DCC's conformity enumeration value of a verdict (INDETERMINATE has none)."""
    return DCC_CONFORMITY.get(verdict or "")
