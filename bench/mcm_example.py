"""The JCGM 101 examples of docs/validation.md ("JCGM 101"), each one case printed whole: the
inputs, the GUM statement (dsp.uncertainty.combine) and the Monte Carlo interval with the
clause 8 verdict (dsp.mcm.validate_line), from the same inputs in the same run.

1. rectangular half-width 1 % plus normal sigma 0.2 %, p = 95 %: against the exact 97.5 %
   quantile of the convolution (closed form);
2. type A alone, nu = 3, p = 95 %: k = t(0.975, 3);
3. type A 0.2 % with nu = 3 plus a rectangular half-width 0.5 %, p = 95 % (the case of
   tests/dsp/test_mcm.py::test_clause_8_flags_l_4_type_a_meeting_a_large_rectangular_term);
   then the same inputs but nu = 6, the dof the periodic estimator states from L = 4 periods
   (2 (L - 1)): a second case, printed as such.

Run: python bench/mcm_example.py   (10^6 trials a case, seconds; --smoke: 10^4 trials)
"""

from __future__ import annotations

import logging
import math
import sys
from pathlib import Path

from scipy import optimize, stats

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from dsp.mcm import DEFAULT_TRIALS, validate_line
from dsp.uncertainty import Budget, Component, combine

log = logging.getLogger("mcm_example")
TRIALS = 10_000 if "--smoke" in sys.argv[1:] else DEFAULT_TRIALS


def rect_plus_normal_quantile(a: float, sigma: float, p: float) -> float:
    """The p quantile of U(-a, a) + N(0, sigma^2) (CDF in closed form, solved by brentq)."""

    def g(z: float) -> float:
        return z * stats.norm.cdf(z) + stats.norm.pdf(z)

    def cdf(x: float) -> float:
        return sigma / (2 * a) * (g((x + a) / sigma) - g((x - a) / sigma))

    return optimize.brentq(lambda x: cdf(x) - p, 0.0, 2 * (a + 4 * sigma))


def case(
    label: str, type_a: float, dof: float, budget: Budget, probability: float, seed: int
) -> None:
    """One case: its inputs, the GUM statement, the Monte Carlo interval and the verdict."""
    gum = combine(type_a, dof, budget, 1250.0, probability=probability)
    line = validate_line(type_a, dof, budget, 1250.0, gum, trials=TRIALS, seed=seed)
    log.info(
        "%s, p = %g %%: u_c %.4f %%, nu_eff %.1f, k %.4f; %s (%d trials, seed %d)",
        label,
        100 * probability,
        100 * gum.standard,
        gum.dof,
        gum.coverage_factor,
        line.summary(),
        TRIALS,
        seed,
    )


def main() -> None:
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    a, sigma = 0.01, 0.002
    exact = rect_plus_normal_quantile(a, sigma, 0.975)
    log.info("1. exact 97.5 %% quantile of U(-1 %%, 1 %%) + N(0, 0.2 %%): %.4f %%", 100 * exact)
    both = Budget((Component("r", a), Component("n", 2 * sigma, "normal")))
    case("1. rectangular a = 1 % + normal sigma = 0.2 %", 0.0, math.inf, both, 0.95, 1)
    case("2. type A 0.2 % alone, nu = 3", 0.002, 3.0, Budget(), 0.95, 2)
    rect = Budget((Component("reference", 0.005),))
    case("3. type A 0.2 %, nu = 3, + rectangular a = 0.5 %", 0.002, 3.0, rect, 0.95, 3)
    case(
        "   the same inputs with nu = 6 (periodic estimator, L = 4 periods)",
        0.002,
        6.0,
        rect,
        0.95,
        3,
    )


if __name__ == "__main__":
    main()
