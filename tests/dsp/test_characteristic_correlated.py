"""Issue 25 point 4: the characteristic's U by the correlated model (dsp.characteristic):
common factors (reference calibration, gains, DAQ gain, temperature) cancel in S(f)/S(f_ref),
the reference line's type A is added. Expected values by hand (GUM 5.1.2, G.4.1)."""

from __future__ import annotations

import dataclasses
import math

import pytest
from scipy import stats

from dsp.annex_a import ComponentKind as K
from dsp.characteristic import (
    characteristic,
    is_common,
    line_deviation_expanded_percent,
    ratio_uncertainty,
)
from dsp.uncertainty import Budget, Component, Distribution, Law

BUDGET = Budget(
    (
        Component(
            "ref cal",
            0.01,
            Distribution.NORMAL,
            coverage_factor=2.0,
            kind=(K.REFERENCE_CALIBRATION,),
        ),
        Component("gain", 0.002, kind=(K.AMPLIFIER_GAIN,)),
        Component("daq", 0.001, kind=(K.DAQ_GAIN, K.DAQ_LINEARITY)),  # linearity does not cancel
        Component("mount", 0.003, kind=(K.MOUNTING,)),
        Component("hf ref", 0.004, kind=(K.REFERENCE_CALIBRATION,), min_frequency_hz=2000.0),
        Component(
            "temp growing",
            0.002,
            kind=(K.TEMPERATURE,),
            law=Law.POWER,
            law_frequency_hz=160.0,
            law_exponent=1.0,
        ),
    )
)


def test_only_constant_common_factors_applying_at_both_lines_cancel() -> None:
    common = {c.name for c in BUDGET.components if is_common(c, 1000.0, 160.0)}
    assert common == {"ref cal", "gain"}
    assert {c.name for c in BUDGET.components if is_common(c, 3000.0, 160.0)} == common


def test_ratio_uncertainty_by_hand() -> None:
    f, f0 = 1000.0, 160.0
    u_a, u_a0, nu = 0.001, 0.0005, 7.0
    got = ratio_uncertainty(u_a, nu, u_a0, nu, BUDGET, f, f0)
    daq = 0.001 / math.sqrt(3)
    mount = 0.003 / math.sqrt(3)
    temp = 0.002 * (1000.0 / 160.0) / math.sqrt(3)
    u = math.sqrt(u_a**2 + u_a0**2 + daq**2 + mount**2 + temp**2)
    nu_eff = u**4 / (u_a**4 / nu + u_a0**4 / nu)
    k = stats.t.ppf(0.5 + 0.9545 / 2, nu_eff)
    assert got.standard == pytest.approx(u, rel=1e-12)
    assert got.dof == pytest.approx(nu_eff, rel=1e-9)
    assert got.expanded == pytest.approx(k * u, rel=1e-6)
    absolute = math.sqrt(u**2 - u_a0**2 + 0.005**2 + (0.002 / math.sqrt(3)) ** 2)
    assert got.standard < absolute  # the common 0.5 % of the reference calibration is gone


def test_the_stored_value_is_used_and_old_results_keep_the_old_formula(recording_results) -> None:
    results = recording_results
    line = results.lines[2]
    assert math.isfinite(line.deviation_expanded_percent)
    assert characteristic(results).deviation_expanded_percent[2] == line.deviation_expanded_percent
    old = dataclasses.replace(line, deviation_expanded_percent=math.nan)
    assert line_deviation_expanded_percent(old) == pytest.approx(
        100 * old.relative_expanded_uncertainty * (1 + old.deviation_percent / 100)
    )
    reference = next(ln for ln in results.lines if ln.deviation_percent == 0.0)
    assert reference.deviation_expanded_percent == 0.0  # 0 by definition (issue 32 point 7)


@pytest.fixture(scope="module")
def recording_results():
    """A synthetic low-pass DUT over the seed's plan, analysed with BUDGET (8 periods)."""
    from app.procedure.analysis import analyze
    from dsp.multisine import make_plan
    from tests.synthetic import lowpass_response, make_recording

    plan = make_plan(PLAN_FREQUENCIES, 6000, 12000, 5.0, 160.0)
    rec = make_recording(plan, lowpass_response(), periods=8, dut_noise_v=1e-4, budget=BUDGET)
    return analyze(rec).results


PLAN_FREQUENCIES = (20.0, 50.0, 160.0, 500.0, 2500.0)
