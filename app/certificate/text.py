"""Every sentence the certificate states (PDF and DCC), in one place; numbers come in already
printed (app.certificate.printed) or as the run stored them. The decision rule's own wording
is dsp.conformity's; here it is only placed into sentences.

Strings for the PDF may carry reportlab's paragraph mark-up (<b>); the DCC's carry none.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from app.io.vocabulary import Mode
from app.records.run_record import RunRecord
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


def method_text(record: RunRecord, results: Results, plan: dict[str, Any]) -> str:
    """The PDF's method paragraph: ISO 16063-21 comparison and the excitation of `record`."""
    lines = plan.get("lines", [])
    freqs = [ln["nominal_frequency_hz"] for ln in lines]
    span = f"{min(freqs):g} Hz to {max(freqs):g} Hz" if freqs else ""
    period_s = plan.get("period_samples", 0) / plan.get("sample_rate_hz", 1)
    excitation = (
        f"multisine excitation: {len(freqs)} frequencies at once (ISO 266 one-third-octave "
        f"values, {span}), each on a DFT bin of a {period_s:g} s "
        f"period sampled at {plan.get('sample_rate_hz', 0):g} Hz, phases optimised for a low "
        "crest factor, table acceleration equalised per frequency in closed loop"
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
    plan = dict(record.plan)
    lines = len(plan.get("lines", []) or results.lines)
    return (
        f"Back-to-back comparison with a reference accelerometer, multisine of {lines} lines, "
        f"{plan.get('sample_rate_hz', 0):g} S/s, period of {plan.get('period_samples', 0)} "
        f"samples, {results.periods} periods, estimator {results.estimator}"
    )


def line_table_note(phase_stated: bool) -> str:
    """The note under the table of results per frequency."""
    return (
        "Deviation: sensitivity relative to the sensitivity at the reference frequency. "
        "U: expanded "
        "uncertainty with the coverage factor k of its line. ISO 16063-21: relative expanded "
        "uncertainty within the standard's suggested limits (2 % to 1 kHz, 4 % to 2 kHz, 6 % "
        "to 10 kHz) or over them; n/s: not stated (no expanded uncertainty"
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


def conformity_summary(verdicts: Sequence[str | None]) -> str:
    """The item's conformity from its per-line tolerance verdicts."""
    if all(v == Outcome.PASS for v in verdicts):
        return "conforms"
    if any(v == Outcome.FAIL for v in verdicts):
        return "does not conform"
    if NOT_STATED in verdicts:
        return (
            "conformity not stated (no expanded uncertainty stated at "
            f"{list(verdicts).count(NOT_STATED)} frequencies)"
        )
    return "no statement of conformity can be made at every frequency"


def conformity_statement(tolerance_percent: float, verdicts: Sequence[str | None]) -> str:
    """The PDF's statement of conformity against a ±tolerance of the characteristic."""
    v = list(verdicts)
    return (
        f"Specification: deviation of the sensitivity from its value at the reference "
        f"frequency within ±{tolerance_percent:g} %. Decision rule: {DECISION_RULE}. Result: "
        f"the item <b>{conformity_summary(v)}</b> ({v.count(Outcome.PASS)} pass, "
        f"{v.count(Outcome.FAIL)} fail, {v.count(Outcome.INCONCLUSIVE)} inconclusive, "
        f"{v.count(NOT_STATED)} not stated of {len(v)})."
    )


def dcc_declaration(verdict: str | None, reasons: Sequence[str]) -> str:
    """The DCC's statement of conformity: the overall verdict, the rule and the reasons."""
    joined = "; ".join(reasons)
    return f"Overall verdict: {verdict or 'not stated'}. Decision rule: {DECISION_RULE}." + (
        f" Reasons: {joined}." if joined else ""
    )


def dcc_conformity(verdict: str | None) -> str | None:
    """The DCC's conformity enumeration value of a verdict (INDETERMINATE has none)."""
    return DCC_CONFORMITY.get(verdict or "")
