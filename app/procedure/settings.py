"""How to run: RunSettings (periods, targets, tolerances, bounds) and the modes."""

from __future__ import annotations

from dataclasses import dataclass

from app.io.quantities import STEPPED_BLOCK
from app.procedure.modes import (
    DEFAULT_STEPPED_BLOCK_S,
    MODE_MULTISINE,
    MODE_STEPPED_SINE,
    MODES,
    Mode,
)
from dsp.estimators import ESTIMATORS, RULES, Estimator, UncertaintyRule
from dsp.spectral import RECORD_ESTIMATORS, check_periods

__all__ = [
    "DEFAULT_STEPPED_BLOCK_S",
    "MODES",
    "MODE_MULTISINE",
    "MODE_STEPPED_SINE",
    "STEPPED_BLOCK_RANGE_S",
    "RunSettings",
]

STEPPED_BLOCK_RANGE_S = (STEPPED_BLOCK.low, STEPPED_BLOCK.high)  # the blocks a run accepts (s)


@dataclass(frozen=True)
class RunSettings:
    """How to run: periods, targets, tolerances and bounds (units in the names)."""

    periods: int = 8
    target_type_a: float | None = None
    max_acquisition_s: float | None = None
    # the bound above is the default of a run with a type A target (app.procedure.stopping),
    # not one the operator gave: the run's report says so
    max_acquisition_default: bool = False
    background_periods: int = 2
    fade_out_s: float | None = None  # None: dsp.fades.fade_out_samples (1.5 cycles)
    # lpm: the fade-in before the analysed record; None: app.procedure.preflight.fade_in_for
    fade_in_s: float | None = None
    settle_tolerance: float = 0.002
    max_settle_periods: int = 12
    equalisation_tolerance: float = 0.01
    max_equalisation_iterations: int = 8
    identification_drive_v: float = 1e-3
    estimator: Estimator = Estimator.PERIODIC
    probability: float = 0.9545
    rule: UncertaintyRule = UncertaintyRule.GUM
    tolerance_percent: float | None = None
    dut_nominal_mv_per_ms2: float | None = None
    plausible_ratio: float = 2.0
    mode: Mode = Mode.MULTISINE
    stepped_block_s: float = DEFAULT_STEPPED_BLOCK_S
    dut_mass_g: float | None = None  # its mass class picks the stored stand response
    stored_response_max_age_days: float = 30.0  # an older stored response is not used
    # a stored response off by more than this at its first check is dropped: re-identify
    stored_response_tolerance: float = 0.1
    resonance: bool = False  # search the mounted resonance in the response (dsp.resonance)

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ValueError(f"mode: one of {', '.join(MODES)}, got {self.mode!r}")
        if self.estimator not in ESTIMATORS:
            raise ValueError(f"estimator: one of {', '.join(ESTIMATORS)}, got {self.estimator!r}")
        if self.rule not in RULES:
            raise ValueError(f"rule: one of {', '.join(RULES)}, got {self.rule!r}")
        # the stored strings typed once here (a plain string given is the same member)
        object.__setattr__(self, "mode", Mode(self.mode))
        object.__setattr__(self, "estimator", Estimator(self.estimator))
        object.__setattr__(self, "rule", UncertaintyRule(self.rule))
        if self.target_type_a is None:
            check_periods(self.estimator, self.periods)  # issue 13 point 5: MIN_PERIODS
        if self.target_type_a is not None and not 0 < self.target_type_a < 1:
            raise ValueError("target type A: must be a fraction between 0 and 1 (0.002 = 0.2 %)")
        if self.max_acquisition_s is not None and not self.max_acquisition_s > 0:
            raise ValueError("max time: must be > 0 s")
        low, high = STEPPED_BLOCK_RANGE_S
        if not low <= self.stepped_block_s <= high:  # NaN too
            raise ValueError(f"stepped block: must be between {low:g} and {high:g} s")
        if not 0 < self.equalisation_tolerance < 0.5:
            raise ValueError("equalisation tolerance: must be between 0 and 0.5")
        if self.fade_out_s is not None and not 0.001 <= self.fade_out_s <= 60:
            raise ValueError("fade-out: must be between 0.001 and 60 s")
        if self.dut_mass_g is not None and not (0 <= self.dut_mass_g <= 100_000):
            raise ValueError("DUT mass: must be between 0 and 100000 g")
        if not self.stored_response_max_age_days >= 0:
            raise ValueError("stored response max age: must be >= 0 days")
        if not self.equalisation_tolerance < self.stored_response_tolerance <= 1:
            raise ValueError(
                "stored response tolerance: must be above the equalisation tolerance and <= 1"
            )
        if self.estimator in RECORD_ESTIMATORS and self.mode != Mode.MULTISINE:
            raise ValueError(f"estimator: {self.estimator} analyses a multisine record only")
        if self.fade_in_s is not None and not 0.001 <= self.fade_in_s <= 60:
            raise ValueError("fade-in: must be between 0.001 and 60 s")
