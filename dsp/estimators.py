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
# A new multisine run's estimator (issue 34): the one-period LPM, its start-up transient
# estimated and the DUT's nonlinear distortion carried (dsp.lpm_record); `periodic` stays for
# averaging over settled periods and `seed` for the seed's protocol. A stored run is read with
# the estimator its results.json names (app.records.run_record.AnalysisSettings: `periodic`
# when it names none, as every run before issue 26 was).
DEFAULT_ESTIMATOR = Estimator.LPM
# A recording that names no estimator (CSV, TDMS, a bare HDF5 file, a run from before the
# setting): its periods averaged
RECORDING_ESTIMATOR = Estimator.PERIODIC
DEFAULT_PERIODS = 8  # periods acquired by default by the estimators that average periods


def default_estimator(mode: str) -> Estimator:
    """A run's estimator when none is given: the LPM for a multisine; the stepped sine's
    sine fits are averaged over blocks (periodic), the LPM analysing a multisine record."""
    return DEFAULT_ESTIMATOR if mode != "stepped-sine" else Estimator.PERIODIC


def default_periods(estimator: str) -> int:
    """The periods a run acquires when none are given: one record of one period (lpm; a type
    A target adds periods), else DEFAULT_PERIODS."""
    return 1 if estimator == Estimator.LPM else DEFAULT_PERIODS


RULES = tuple(r.value for r in UncertaintyRule)
