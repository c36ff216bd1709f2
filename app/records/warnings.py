"""Which warnings block PASS and the certificate, and which are printed on it (issue 25
point 2; docs/validation.md "Blocking warnings" holds the same table in words).

Warnings travel as one-line texts (dsp.calibration, dsp.hum, dsp.multisine, the procedure);
`classify` gives each its kind by the wording its producer uses, `blocking` picks the ones
that keep a run from PASS and from a certificate, `printed` the ones the certificate must
print. A warning of no known kind is printed (never silently dropped). No I/O.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from dataclasses import dataclass
from enum import StrEnum

from dsp.annex_a import incomplete_budget_text, missing_components
from dsp.uncertainty import Budget

__all__ = [
    "POLICY",
    "SEED_RULE_WARNING",
    "Policy",
    "RunWarning",
    "WarningKind",
    "blocking",
    "budget_warning",
    "classify",
    "incomplete_budget_warning",
    "iso_over_warning",
    "printed",
]


class WarningKind(StrEnum):
    """What a warning is about."""

    INCOMPLETE_BUDGET = "incomplete budget"
    IMPLAUSIBLE_BUDGET = "implausible budget"
    NO_CMC = "no CMC"
    NO_UNCERTAINTY = "no uncertainty"
    LOW_COHERENCE = "low coherence"
    LOW_SNR = "low SNR"
    DUT_DISTORTION = "DUT distortion"
    NONLINEAR_CARRIED = "nonlinear distortion carried"
    NONLINEAR_NOT_COVERED = "nonlinear distortion not covered"
    HUM_NOT_SEPARABLE = "hum not separable"
    HUM_MEASURED = "hum measured"
    ISO_OVER = "ISO over"
    REFERENCE_REFUSED = "reference extrapolation refused"
    REFERENCE_EXTRAPOLATED = "reference extrapolated"
    SEED_RULE = "seed rule"
    SKEW_NOT_CORRECTED = "skew not corrected"
    MOUNTING = "mounting"
    ADC_RESOLUTION = "ADC resolution"
    GUM_NOT_VALIDATED = "GUM not validated"
    PLAN = "plan"
    TYPE_A_TARGET = "type A target not met"
    OTHER = "other"


class Policy(StrEnum):
    """BLOCKS: no PASS, no certificate. PRINTED: the certificate states it."""

    BLOCKS = "blocks PASS and the certificate"
    PRINTED = "printed on the certificate"


@dataclass(frozen=True)
class Rule:
    """One row of the table: the policy, why, and the wording that identifies the kind."""

    policy: Policy
    why: str
    pattern: str  # regular expression searched in the warning text; "" matches nothing


POLICY: dict[WarningKind, Rule] = {
    WarningKind.INCOMPLETE_BUDGET: Rule(
        Policy.BLOCKS,
        "the stated U leaves out ISO 16063-21 Annex A components: results for review only",
        r"^(no type B budget|incomplete budget)",
    ),
    WarningKind.IMPLAUSIBLE_BUDGET: Rule(
        Policy.BLOCKS,
        "a component stands for several Annex A kinds or is below its kind's plausible minimum",
        r"^implausible budget",
    ),
    WarningKind.NO_CMC: Rule(
        Policy.BLOCKS,
        "no CMC of the laboratory bounds the stated U at a line (ILAC P14)",
        r"^no CMC",
    ),
    WarningKind.NO_UNCERTAINTY: Rule(
        Policy.BLOCKS,
        "no type A uncertainty could be stated",
        r"^one period only|estimator states a type A uncertainty from",
    ),
    WarningKind.LOW_COHERENCE: Rule(
        Policy.BLOCKS,
        "the response is not linear and noise-free at the line: U does not cover it",
        r": low coherence ",
    ),
    WarningKind.LOW_SNR: Rule(
        Policy.BLOCKS,
        "under 20 dB the estimators' bias is not in the budget",
        r" SNR [-\d.]+ dB is below ",
    ),
    WarningKind.DUT_DISTORTION: Rule(
        Policy.BLOCKS,
        "over 1 % distortion the DUT is not calibrated at a sinusoidal level (ISO 16063-21)",
        r"the DUT adds [\d.]+ % harmonic distortion",
    ),
    WarningKind.NONLINEAR_CARRIED: Rule(
        Policy.PRINTED,
        "the DUT's distortion measured at the detection bins: the best linear approximation at "
        "this excitation is stated, its stochastic part removed and its estimate in U",
        r"^nonlinear distortion of the DUT: ",
    ),
    WarningKind.NONLINEAR_NOT_COVERED: Rule(
        Policy.BLOCKS,
        "distortion the order 2-3 model does not explain: U does not cover it at the named lines",
        r"^nonlinear distortion at lines ",
    ),
    WarningKind.HUM_NOT_SEPARABLE: Rule(
        Policy.BLOCKS,
        "hum at the line was not measured, only guessed from other bins, or sits within a "
        "fifth of a bin of the line while driven",
        r"mains hum .*not separable|hum while driven .*not separable",
    ),
    WarningKind.HUM_MEASURED: Rule(
        Policy.PRINTED,
        "measured with the drive off, or while driven beside the line, and carried in the "
        "budget at its size",
        r"mains hum at .*drive-off|hum while driven .*in the budget",
    ),
    WarningKind.ISO_OVER: Rule(
        Policy.BLOCKS,
        "U over the ISO 16063-21 suggested limit",
        r"over the ISO 16063-21 limit",
    ),
    WarningKind.REFERENCE_REFUSED: Rule(
        Policy.BLOCKS,
        "outside the reference's certificate with no stated extrapolation term",
        r"outside the reference certificate('s range; extrapolated|.*: refused)",
    ),
    WarningKind.REFERENCE_EXTRAPOLATED: Rule(
        Policy.PRINTED,
        "outside the reference's certificate, carried by the stand's extrapolation term",
        r"outside the reference certificate.*stated extrapolation term",
    ),
    WarningKind.SEED_RULE: Rule(
        Policy.BLOCKS,
        "k from t(L-1) ignores the type B dof (GUM G.4.1): kept to reproduce the paper",
        r"^seed rule",
    ),
    WarningKind.SKEW_NOT_CORRECTED: Rule(
        Policy.BLOCKS,
        "the phase characteristic is not stated",
        r"^phase not corrected for skew",
    ),
    WarningKind.MOUNTING: Rule(
        Policy.BLOCKS,
        "a resonance or rattle inside the calibrated range: the mounting is suspect",
        r"^mounting: ",
    ),
    WarningKind.ADC_RESOLUTION: Rule(
        Policy.BLOCKS,
        "a line too few LSB above the converter's step: its resolution is not stated "
        "(dsp.resolution); re-ranged or raised, never PASS",
        r" LSB on its \+-[\d.e+-]+ V range \(< [\d.]+ LSB\): resolution not stated",
    ),
    WarningKind.GUM_NOT_VALIDATED: Rule(
        Policy.PRINTED,
        "the GUM interval failed JCGM 101 clause 8: the Monte Carlo interval is stated",
        r"JCGM 101",
    ),
    WarningKind.PLAN: Rule(
        Policy.PRINTED,
        "a property of the frequency plan (snapped line, harmonic or mains bin)",
        r": snapped to |lands on its bin|mains harmonic \(",
    ),
    WarningKind.TYPE_A_TARGET: Rule(
        Policy.PRINTED,
        "the time bound ended the run before the operator's type A target: each line is stated "
        "with the type A measured, which its U carries, and conformity is decided with that U",
        r"^type A target .* not met: ",
    ),
    WarningKind.OTHER: Rule(Policy.PRINTED, "not classified: printed", ""),
}

SEED_RULE_WARNING = (
    "seed rule: k from Student t with L - 1 dof whatever the type B budget; this is not GUM "
    "(G.4.1 takes nu_eff by Welch-Satterthwaite over all components), kept to reproduce the paper"
)


@dataclass(frozen=True)
class RunWarning:
    """A warning with its kind; `policy` from the table."""

    kind: WarningKind
    text: str

    @property
    def policy(self) -> Policy:
        return POLICY[self.kind].policy


def classify(text: str) -> RunWarning:
    """The warning's kind from its wording (table order; OTHER if none matches)."""
    for kind, rule in POLICY.items():
        if rule.pattern and re.search(rule.pattern, text):
            return RunWarning(kind, text)
    return RunWarning(WarningKind.OTHER, text)


def _typed(warnings: Iterable[str | RunWarning]) -> list[RunWarning]:
    return [w if isinstance(w, RunWarning) else classify(w) for w in warnings]


def blocking(warnings: Iterable[str | RunWarning]) -> list[RunWarning]:
    """The warnings that keep a run from PASS and from a certificate, in order."""
    return [w for w in _typed(warnings) if w.policy is Policy.BLOCKS]


def printed(warnings: Iterable[str | RunWarning]) -> list[RunWarning]:
    """The warnings a certificate prints (every one that does not block), in order."""
    return [w for w in _typed(warnings) if w.policy is Policy.PRINTED]


def incomplete_budget_warning(missing: Iterable[str]) -> RunWarning:
    """The blocking warning for a budget lacking Annex A components (dsp.annex_a)."""
    return RunWarning(WarningKind.INCOMPLETE_BUDGET, incomplete_budget_text(missing))


def budget_warning(budget: Budget) -> RunWarning | None:
    """The blocking "incomplete budget" warning when `budget` (the stand's, before the
    procedure adds its measured terms) lacks Annex A components; None for a full one."""
    missing = missing_components(budget)
    return incomplete_budget_warning(missing) if missing else None


def iso_over_warning(frequency_hz: float, relative_expanded: float, limit: float) -> RunWarning:
    """The blocking warning for a line whose U (fraction) is over the ISO limit (fraction)."""
    return RunWarning(
        WarningKind.ISO_OVER,
        f"line {frequency_hz:g} Hz: U = {100 * relative_expanded:.3g} % is over the ISO "
        f"16063-21 limit {100 * limit:g} %",
    )


def table_markdown() -> str:
    """The table as Markdown rows (docs/validation.md is checked against it)."""
    rows = ["| warning | policy | why |", "|---|---|---|"]
    rows += [f"| {k.value} | {r.policy.value} | {r.why} |" for k, r in POLICY.items()]
    return "\n".join(rows)
