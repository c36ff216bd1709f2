"""The estimators' names and the uncertainty's coverage rules: the one vocabulary (CLI, GUI,
settings, results.json), importable without numpy/scipy. StrEnums: the members are the stored
strings themselves."""

from enum import StrEnum


class Estimator(StrEnum):
    """How a line's transfer function is estimated from the acquired periods."""

    PERIODIC = "periodic"
    H1 = "h1"
    SEED = "seed"
    LPM = "lpm"  # one record (dsp.lpm_record)


class UncertaintyRule(StrEnum):
    """How the coverage factor k is found: GUM G.6.4 from nu_eff, or the seed's k = t(L-1)."""

    GUM = "gum"
    SEED = "seed"


ESTIMATORS = tuple(e.value for e in Estimator)  # plain strings: argparse quotes choices by repr()
DEFAULT_ESTIMATOR = Estimator.PERIODIC
RULES = tuple(r.value for r in UncertaintyRule)
