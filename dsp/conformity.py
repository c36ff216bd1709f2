"""The one ILAC-G8 decision rule (guarded acceptance) and its wording; units are the caller's.

Every face (the verdict of a run, the per-line tolerance verdicts, the PDF, the DCC, the GUI)
decides and words a conformity statement through this module: `decide` for one check,
`DECISION_RULE` for the sentence that states the rule, `Verdict` / `Outcome` for the words.
Reference: ILAC-G8:09/2019, section 4.2.2 (guarded acceptance with a guard band w = U).
"""

from __future__ import annotations

import math
from enum import StrEnum


class Verdict(StrEnum):
    """The overall verdict of a run; serialises to the strings stored in results.json."""

    PASS = "PASS"
    FAIL = "FAIL"
    INDETERMINATE = "INDETERMINATE"


class Outcome(StrEnum):
    """The outcome of one check; serialises to the strings stored in results.json."""

    PASS = "pass"
    FAIL = "fail"
    INCONCLUSIVE = "inconclusive"
    NOT_STATED = "not stated"  # the check needs an uncertainty: 0, undefined or below its floor


NOT_STATED = Outcome.NOT_STATED

# The rule in words (PDF, DCC, GUI); U and the deviation in the same unit.
DECISION_RULE = (
    "guarded acceptance (ILAC-G8:09/2019): a check passes where |deviation| + U ≤ tolerance, "
    "fails where |deviation| − U > tolerance, and is inconclusive otherwise"
)
DECISION_RULE_SHORT = "guarded acceptance (ILAC-G8) against the DUT's tolerances"


def uncertainty_stated(expanded: float, floor: float = 0.0) -> bool:
    """True when an expanded uncertainty can support a statement: finite, > 0 and not below
    `floor` (same unit: the laboratory's CMC, or the plausible floor of a full budget,
    dsp.annex_a.plausible_floor; a U under it is rounding noise or a budget left out)."""
    return math.isfinite(expanded) and expanded > 0 and not expanded < floor


def decide(deviation: float, expanded: float, tolerance: float, floor: float = 0.0) -> Outcome:
    """Guarded acceptance of |deviation| against `tolerance` with expanded uncertainty
    `expanded` (all three in one unit, e.g. % or degrees): PASS if |dev| + U <= T, FAIL if
    |dev| - U > T, otherwise INCONCLUSIVE; NOT_STATED when U is 0, negative, not finite or
    below `floor` (same unit; see uncertainty_stated)."""
    if not uncertainty_stated(expanded, 0.0 if math.isnan(floor) else floor):
        return Outcome.NOT_STATED
    if not math.isfinite(deviation):
        return Outcome.INCONCLUSIVE
    if abs(deviation) + expanded <= tolerance:
        return Outcome.PASS
    if abs(deviation) - expanded > tolerance:
        return Outcome.FAIL
    return Outcome.INCONCLUSIVE
