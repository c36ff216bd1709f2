"""Tests of dsp.uncertainty against SPEC.md section 7 and JCGM 100:2008 (GUM)."""

from __future__ import annotations

import json
import math
from dataclasses import FrozenInstanceError, fields

import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy import stats

from dsp.uncertainty import (
    Budget,
    Combined,
    Component,
    Distribution,
    Quantity,
    Verdict,
    combine,
    coverage_factor,
    iso_16063_21_limit,
    iso_verdict,
    seed_coverage_factor,
    welch_satterthwaite,
)

MAG = Quantity.MAGNITUDE
PHASE = Quantity.PHASE


# --- Component: distributions and validation ---------------------------------------------


@pytest.mark.parametrize(
    ("distribution", "divisor"),
    [
        (Distribution.RECTANGULAR, math.sqrt(3)),
        (Distribution.TRIANGULAR, math.sqrt(6)),
        (Distribution.U_SHAPED, math.sqrt(2)),
        (Distribution.STANDARD, 1.0),
    ],
)
def test_half_width_divisors(distribution: Distribution, divisor: float) -> None:
    c = Component("x", 0.03, distribution)
    assert c.standard_uncertainty == pytest.approx(0.03 / divisor, rel=1e-15)


@pytest.mark.parametrize("k", [1.0, 2.0, 2.58, 3.0])
def test_normal_divides_by_its_coverage_factor(k: float) -> None:
    c = Component("ref cal", 0.006, Distribution.NORMAL, coverage_factor=k)
    assert c.standard_uncertainty == pytest.approx(0.006 / k, rel=1e-15)


def test_coverage_factor_ignored_for_other_distributions() -> None:
    c = Component("x", 0.03, Distribution.RECTANGULAR, coverage_factor=3.0)
    assert c.standard_uncertainty == pytest.approx(0.03 / math.sqrt(3))


def test_component_defaults() -> None:
    c = Component("x", 0.01)
    assert c.distribution is Distribution.RECTANGULAR
    assert c.quantity is Quantity.MAGNITUDE
    assert c.coverage_factor == 2.0
    assert math.isinf(c.dof)
    assert c.min_frequency_hz is None and c.max_frequency_hz is None


def test_enum_values_are_the_documented_strings() -> None:
    assert [d.value for d in Distribution] == [
        "normal",
        "rectangular",
        "triangular",
        "u-shaped",
        "standard",
    ]
    assert [q.value for q in Quantity] == ["magnitude", "phase"]
    assert [v.value for v in Verdict] == ["within", "over", "n/a"]


def test_string_distribution_is_coerced_to_the_enum() -> None:
    c = Component("x", 0.01, "U-Shaped")  # type: ignore[arg-type]
    assert c.distribution is Distribution.U_SHAPED
    assert c.standard_uncertainty == pytest.approx(0.01 / math.sqrt(2))


def test_negative_value_message_names_field_and_component() -> None:
    with pytest.raises(ValueError, match=r"^component 'DAQ gain': value must be >= 0, got -1$"):
        Component("DAQ gain", -1)


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"value": math.nan}, "value"),
        ({"value": math.inf}, "value"),
        ({"value": "0.01"}, "value"),
        ({"dof": 0}, "dof"),
        ({"dof": -3}, "dof"),
        ({"dof": math.nan}, "dof"),
        ({"coverage_factor": 0}, "coverage_factor"),
        ({"coverage_factor": -2}, "coverage_factor"),
        ({"distribution": "gaussian"}, "distribution"),
        ({"quantity": "amplitude"}, "quantity"),
        ({"min_frequency_hz": 100.0, "max_frequency_hz": 10.0}, "min_frequency_hz"),
        ({"min_frequency_hz": math.nan}, "min_frequency_hz"),
        ({"max_frequency_hz": -1.0}, "max_frequency_hz"),
    ],
)
def test_component_validation_names_field_and_component(kwargs: dict, field: str) -> None:
    args = {"name": "mounting", "value": 0.01} | kwargs
    with pytest.raises(ValueError, match=rf"component 'mounting': {field}"):
        Component(**args)


def test_component_needs_a_name() -> None:
    with pytest.raises(ValueError, match="name"):
        Component("  ", 0.01)


def test_infinite_dof_and_equal_bounds_are_allowed() -> None:
    c = Component("x", 0.0, dof=math.inf, min_frequency_hz=80.0, max_frequency_hz=80.0)
    assert c.applies_at(80.0)
    assert not c.applies_at(80.0001)
    assert c.standard_uncertainty == 0.0


def test_component_is_frozen() -> None:
    c = Component("x", 0.01)
    with pytest.raises(AttributeError):
        c.value = 0.02  # type: ignore[misc]


# --- frequency ranges and the budget ----------------------------------------------------


def test_applies_at_is_inclusive_and_none_is_unbounded() -> None:
    band = Component("x", 0.01, min_frequency_hz=1000.0, max_frequency_hz=2000.0)
    assert not band.applies_at(999.999)
    assert band.applies_at(1000.0)
    assert band.applies_at(1500.0)
    assert band.applies_at(2000.0)
    assert not band.applies_at(2000.001)
    low = Component("x", 0.01, max_frequency_hz=100.0)
    assert low.applies_at(0.0) and low.applies_at(100.0) and not low.applies_at(100.5)
    high = Component("x", 0.01, min_frequency_hz=100.0)
    assert high.applies_at(1e6) and not high.applies_at(99.5)
    anywhere = Component("x", 0.01)
    assert anywhere.applies_at(0.0) and anywhere.applies_at(1e9)


def test_applies_at_refuses_nan_frequency() -> None:
    with pytest.raises(ValueError, match="frequency_hz"):
        Component("x", 0.01).applies_at(math.nan)


def _stand_budget() -> Budget:
    return Budget(
        (
            Component("reference calibration", 0.01, Distribution.NORMAL, coverage_factor=2.0),
            Component("DAQ gain", 0.002 * math.sqrt(3)),
            Component("upper band", 0.03, Distribution.STANDARD, min_frequency_hz=1000.5),
            Component("low band", 0.004, Distribution.STANDARD, dof=10, max_frequency_hz=1000.0),
            Component("phase ref", 0.5, Distribution.STANDARD, quantity=PHASE, dof=8),
        )
    )


def test_budget_at_selects_by_frequency_and_quantity() -> None:
    b = _stand_budget()
    assert [c.name for c in b.at(1000.0, MAG)] == ["reference calibration", "DAQ gain", "low band"]
    assert [c.name for c in b.at(2000.0, MAG)] == [
        "reference calibration",
        "DAQ gain",
        "upper band",
    ]
    assert [c.name for c in b.at(80.0, PHASE)] == ["phase ref"]


def test_budget_type_b_root_sum_square_and_dof() -> None:
    b = _stand_budget()
    u, nu = b.type_b(160.0, MAG)
    us = [0.005, 0.002, 0.004]
    expected_u = math.sqrt(sum(x * x for x in us))
    assert u == pytest.approx(expected_u, rel=1e-12)
    assert nu == pytest.approx(expected_u**4 / (0.004**4 / 10), rel=1e-12)
    u_hi, nu_hi = b.type_b(5000.0, MAG)
    assert u_hi == pytest.approx(math.sqrt(0.005**2 + 0.002**2 + 0.03**2), rel=1e-12)
    assert math.isinf(nu_hi)
    assert b.type_b(160.0, PHASE) == (pytest.approx(0.5), pytest.approx(8.0))


def test_empty_budget_gives_zero_and_infinite_dof() -> None:
    assert Budget().type_b(100.0, MAG) == (0.0, math.inf)
    assert _stand_budget().type_b(100.0, "phase") == (0.5, pytest.approx(8.0))  # type: ignore[arg-type]


def test_budget_refuses_non_components() -> None:
    with pytest.raises(TypeError, match="budget entry 2"):
        Budget((Component("x", 0.01), {"name": "y", "value": 0.01}))  # type: ignore[arg-type]


def test_seed_equation_18_19_rectangular_mpes() -> None:
    b = Budget.seed_rectangular({"amplitude setting": 0.05, "DAQ": 0.05})
    assert all(c.distribution is Distribution.RECTANGULAR for c in b.components)
    assert [c.name for c in b.components] == ["amplitude setting", "DAQ"]
    u, nu = b.type_b(80.0, MAG)
    assert u == pytest.approx(math.sqrt(0.05**2 + 0.05**2) / math.sqrt(3), rel=1e-14)
    assert math.isinf(nu)
    assert b.type_b(80.0, PHASE) == (0.0, math.inf)


def test_seed_rectangular_validates_values() -> None:
    with pytest.raises(ValueError, match="component 'DAQ': value must be >= 0"):
        Budget.seed_rectangular({"DAQ": -0.01})


# --- serialisation ------------------------------------------------------------------------


def test_component_round_trip_and_json_safe() -> None:
    for c in _stand_budget().components:
        d = c.to_dict()
        assert Component.from_dict(json.loads(json.dumps(d, allow_nan=False))) == c
    d = Component("x", 0.01).to_dict()
    assert d["dof"] is None
    assert d["distribution"] == "rectangular" and d["quantity"] == "magnitude"


def test_budget_round_trip() -> None:
    b = _stand_budget()
    assert Budget.from_list(json.loads(json.dumps(b.to_list(), allow_nan=False))) == b
    assert Budget.from_list([]) == Budget()


@pytest.mark.parametrize("dof", [None, "inf", "Inf", math.inf])
def test_from_dict_infinite_dof_spellings(dof: object) -> None:
    c = Component.from_dict({"name": "x", "value": 0.01, "dof": dof})
    assert math.isinf(c.dof)


def test_from_dict_minimal_uses_defaults() -> None:
    assert Component.from_dict({"name": "x", "value": 0.01}) == Component("x", 0.01)


@pytest.mark.parametrize(
    ("d", "pattern"),
    [
        ({"name": "temp"}, r"component 'temp': missing key 'value'"),
        ({"value": 0.01}, r"component <unnamed>: missing key 'name'"),
        ({"name": "temp", "valu": 0.01, "value": 0.0}, r"component 'temp': unknown key 'valu'"),
        ({"name": "temp", "value": "1 %"}, r"component 'temp': value must be a number"),
        ({"name": "temp", "value": True}, r"component 'temp': value must be a number"),
        ({"name": "temp", "value": 0.01, "dof": "many"}, r"component 'temp': dof must be"),
        ({"name": "temp", "value": 0.01, "dof": 0}, r"component 'temp': dof must be > 0"),
        (
            {"name": "temp", "value": 0.01, "distribution": "flat"},
            r"component 'temp': distribution must be one of",
        ),
        (
            {"name": "temp", "value": 0.01, "quantity": "gain"},
            r"component 'temp': quantity must be one of",
        ),
        (
            {"name": "temp", "value": 0.01, "min_frequency_hz": "10 Hz"},
            r"component 'temp': min_frequency_hz must be a number",
        ),
        ({"name": "temp", "value": 0.01, "note": 3}, r"component 'temp': note must be"),
    ],
)
def test_from_dict_errors_name_key_and_component(d: dict, pattern: str) -> None:
    with pytest.raises(ValueError, match=pattern):
        Component.from_dict(d)


def test_from_dict_refuses_non_mapping() -> None:
    with pytest.raises(ValueError, match="mapping"):
        Component.from_dict([("name", "x")])  # type: ignore[arg-type]


def test_from_list_error_names_entry() -> None:
    entries = [{"name": "a", "value": 0.01}, {"name": "b", "value": -0.01}]
    with pytest.raises(ValueError, match=r"budget entry 2 of 2: component 'b': value must be >= 0"):
        Budget.from_list(entries)


# --- coverage factor ---------------------------------------------------------------------

# JCGM 100:2008 Table G.2, t_p(nu) as printed (string keeps the printed precision).
GUM_TABLE_G2 = [
    (0.9545, 1, "13.97"),
    (0.9545, 2, "4.53"),
    (0.9545, 3, "3.31"),
    (0.9545, 4, "2.87"),
    (0.9545, 5, "2.65"),
    (0.9545, 6, "2.52"),
    (0.9545, 7, "2.43"),
    (0.9545, 8, "2.37"),
    (0.9545, 9, "2.32"),
    (0.9545, 10, "2.28"),
    (0.9545, 20, "2.13"),
    (0.9545, 50, "2.05"),
    (0.9545, 100, "2.025"),
    (0.9545, math.inf, "2.000"),
    (0.95, 1, "12.71"),
    (0.95, 2, "4.30"),
    (0.95, 3, "3.18"),
    (0.95, 10, "2.23"),
    (0.95, math.inf, "1.960"),
    (0.99, 1, "63.66"),
    (0.99, math.inf, "2.576"),
    (0.6827, 1, "1.84"),
    (0.6827, math.inf, "1.000"),
]


@pytest.mark.parametrize(("p", "nu", "printed"), GUM_TABLE_G2)
def test_coverage_factor_matches_gum_table_g2(p: float, nu: float, printed: str) -> None:
    half_unit = 0.5 * 10.0 ** -len(printed.split(".")[1])
    assert abs(coverage_factor(nu, p) - float(printed)) <= half_unit + 1e-12


@pytest.mark.parametrize("nu", [0.5, 1, 2.5, 3, 7, 16.7, 30, 1000, 1e6])
@pytest.mark.parametrize("p", [0.6827, 0.9, 0.95, 0.9545, 0.99])
def test_coverage_factor_is_student_t(nu: float, p: float) -> None:
    assert coverage_factor(nu, p) == pytest.approx(stats.t.ppf((1 + p) / 2, nu), rel=1e-12)


def test_coverage_factor_default_is_9545_and_tends_to_normal() -> None:
    assert coverage_factor(math.inf) == pytest.approx(stats.norm.ppf(0.97725), rel=1e-12)
    assert coverage_factor(math.inf) == pytest.approx(2.0, abs=1e-3)
    assert coverage_factor(1e9) == pytest.approx(coverage_factor(math.inf), rel=1e-6)
    assert coverage_factor(3) == pytest.approx(stats.t.ppf(0.97725, 3), rel=1e-12)


@pytest.mark.parametrize(
    ("dof", "p", "field"),
    [
        (0, 0.95, "dof"),
        (-1, 0.95, "dof"),
        (math.nan, 0.95, "dof"),
        (5, 0.0, "probability"),
        (5, 1.0, "probability"),
        (5, 95.0, "probability"),
        (5, math.nan, "probability"),
    ],
)
def test_coverage_factor_validates(dof: float, p: float, field: str) -> None:
    with pytest.raises(ValueError, match=field):
        coverage_factor(dof, p)


@pytest.mark.parametrize(
    ("periods", "k"),
    [(2, 12.706), (3, 4.303), (4, 3.182), (8, 2.365), (9, 2.306), (10, 2.0), (32, 2.0)],
)
def test_seed_coverage_factor(periods: int, k: float) -> None:
    assert seed_coverage_factor(periods) == pytest.approx(k, abs=5e-4)


def test_seed_coverage_factor_l4_is_t_975_of_3() -> None:
    assert seed_coverage_factor(4) == pytest.approx(stats.t.ppf(0.975, 3), rel=1e-12)
    assert round(seed_coverage_factor(4), 2) == 3.18
    assert seed_coverage_factor(10) == 2.0


@pytest.mark.parametrize("periods", [1, 0, -4, 4.0, True, "8"])
def test_seed_coverage_factor_refuses_bad_periods(periods: object) -> None:
    with pytest.raises(ValueError, match="periods"):
        seed_coverage_factor(periods)  # type: ignore[arg-type]


# --- Welch-Satterthwaite -----------------------------------------------------------------


def test_welch_satterthwaite_gum_example_h1() -> None:
    # JCGM 100:2008 H.1 (end-gauge calibration), Table H.1: |c_i| u(x_i) in nm and nu_i.
    u = [25.0, 9.7, 2.9, 16.6]
    nu = [18, 25.6, 50, 2]
    u_c = math.sqrt(sum(x * x for x in u))
    assert round(u_c) == 32  # GUM H.1.4: u_c(l) = 32 nm
    nu_eff = welch_satterthwaite(u, nu)
    assert 16.5 <= nu_eff <= 16.9  # GUM H.1.6: nu_eff(l) = 16.7
    # GUM H.1.6 truncates to nu = 16: t_99(16) = 2.92; rounded to 17 instead: 2.90.
    assert round(coverage_factor(math.floor(nu_eff), 0.99), 2) == 2.92
    assert round(coverage_factor(round(nu_eff), 0.99), 2) == 2.90


def test_welch_satterthwaite_edge_cases() -> None:
    assert welch_satterthwaite([0.01], [7]) == pytest.approx(7.0)
    assert math.isinf(welch_satterthwaite([0.01, 0.02], [math.inf, math.inf]))
    assert math.isinf(welch_satterthwaite([0.0, 0.0], [3, 4]))
    assert math.isinf(welch_satterthwaite([], []))
    # an infinite-dof component adds to u_c but nothing to the denominator
    assert welch_satterthwaite([1.0, 1.0], [4, math.inf]) == pytest.approx(4.0 * 4.0)
    # a zero component with finite dof changes nothing
    assert welch_satterthwaite([1.0, 0.0], [4, 2]) == pytest.approx(4.0)
    # two equal components with equal dof: nu_eff = 2 nu
    assert welch_satterthwaite([0.3, 0.3], [5, 5]) == pytest.approx(10.0)
    assert math.isnan(welch_satterthwaite([math.nan, 0.01], [0, math.inf]))


def test_welch_satterthwaite_is_scale_free() -> None:
    u, nu = [3.0, 4.0, 1.0], [5, 9, 2]
    ref = welch_satterthwaite(u, nu)
    for scale in (1e-200, 1e-30, 1e30, 1e150):
        assert welch_satterthwaite([x * scale for x in u], nu) == pytest.approx(ref, rel=1e-12)


@pytest.mark.parametrize(
    ("u", "nu"),
    [([0.1, 0.2], [3]), ([-0.1], [3]), ([math.inf], [3]), ([0.1], [0]), ([0.1], [math.nan])],
)
def test_welch_satterthwaite_validates(u: list, nu: list) -> None:
    with pytest.raises(ValueError, match="welch_satterthwaite"):
        welch_satterthwaite(u, nu)


# --- combine -----------------------------------------------------------------------------


def test_combine_gum_rule() -> None:
    b = _stand_budget()
    res = combine(0.003, 3, b, 160.0)
    assert isinstance(res, Combined)
    u_bi = [0.005, 0.002, 0.004]
    u_c = math.sqrt(0.003**2 + sum(x * x for x in u_bi))
    nu_eff = u_c**4 / (0.003**4 / 3 + 0.004**4 / 10)
    assert res.type_a == 0.003 and res.type_a_dof == 3
    assert res.type_b == pytest.approx(math.sqrt(sum(x * x for x in u_bi)), rel=1e-12)
    assert res.standard == pytest.approx(u_c, rel=1e-12)
    assert res.dof == pytest.approx(nu_eff, rel=1e-12)
    assert res.coverage_probability == 0.9545
    assert res.coverage_factor == pytest.approx(stats.t.ppf(0.97725, nu_eff), rel=1e-12)
    assert res.expanded == pytest.approx(res.coverage_factor * u_c, rel=1e-12)


def test_combine_seed_case_with_type_a() -> None:
    # seed eq. 19/20: u_B = sqrt(0.05^2 + 0.05^2)/sqrt(3), u_c = sqrt(u_A^2 + u_B^2)
    b = Budget.seed_rectangular({"amplitude": 0.05, "DAQ": 0.05})
    u_b = math.sqrt(0.005) / math.sqrt(3)
    res = combine(0.01, 3, b, 80.0, rule="seed", periods=4)
    assert res.type_b == pytest.approx(u_b, rel=1e-14)
    assert res.standard == pytest.approx(math.sqrt(0.01**2 + u_b**2), rel=1e-14)
    assert res.dof == pytest.approx(res.standard**4 / (0.01**4 / 3), rel=1e-12)
    assert res.coverage_factor == pytest.approx(stats.t.ppf(0.975, 3), rel=1e-12)
    assert res.coverage_probability == 0.95
    assert res.expanded == pytest.approx(res.coverage_factor * res.standard, rel=1e-14)
    res32 = combine(0.01, 31, b, 80.0, rule="seed", periods=32)
    assert res32.coverage_factor == 2.0 and res32.coverage_probability == 0.9545  # k = 2, normal


def test_combine_phase_in_degrees_uses_phase_components_only() -> None:
    res = combine(0.2, math.inf, _stand_budget(), 80.0, PHASE)
    assert res.type_b == pytest.approx(0.5)
    assert res.standard == pytest.approx(math.hypot(0.2, 0.5), rel=1e-12)
    assert res.dof == pytest.approx(math.hypot(0.2, 0.5) ** 4 / (0.5**4 / 8), rel=1e-12)


def test_combine_zero_everything() -> None:
    res = combine(0.0, 5, Budget(), 100.0)
    assert res.standard == 0.0 and res.expanded == 0.0
    assert math.isinf(res.dof)
    assert res.coverage_factor == pytest.approx(2.0, abs=1e-3)


@pytest.mark.parametrize("rule", ["gum", "seed"])
@pytest.mark.parametrize("dof", [0, math.nan])
def test_combine_nan_type_a_gives_nan_without_crashing(rule: str, dof: float) -> None:
    res = combine(math.nan, dof, _stand_budget(), 160.0, rule=rule, periods=4)
    assert math.isnan(res.standard) and math.isnan(res.expanded) and math.isnan(res.dof)
    assert res.type_b == pytest.approx(math.sqrt(0.005**2 + 0.002**2 + 0.004**2))
    if rule == "seed":
        assert res.coverage_factor == pytest.approx(stats.t.ppf(0.975, 3))
    else:
        assert math.isnan(res.coverage_factor)
    assert iso_verdict(160.0, res.expanded) is Verdict.OVER


def test_combine_rule_errors() -> None:
    b = _stand_budget()
    with pytest.raises(ValueError, match="rule"):
        combine(0.01, 3, b, 100.0, rule="iso")
    with pytest.raises(ValueError, match="periods"):
        combine(0.01, 3, b, 100.0, rule="seed")
    with pytest.raises(ValueError, match="periods"):
        combine(0.01, 3, b, 100.0, rule="seed", periods=1)


@pytest.mark.parametrize(
    ("type_a", "dof", "field"),
    [(-0.01, 3, "type_a"), (math.inf, 3, "type_a"), (0.01, 0, "type_a_dof")],
)
def test_combine_validates_type_a(type_a: float, dof: float, field: str) -> None:
    with pytest.raises(ValueError, match=field):
        combine(type_a, dof, Budget(), 100.0)


def test_combine_probability_changes_k() -> None:
    b = _stand_budget()
    k95 = combine(0.003, 3, b, 160.0, probability=0.95).coverage_factor
    k99 = combine(0.003, 3, b, 160.0, probability=0.99).coverage_factor
    assert k95 < k99
    with pytest.raises(ValueError, match="probability"):
        combine(0.003, 3, b, 160.0, probability=1.5)


# --- ISO 16063-21 limits -----------------------------------------------------------------


@pytest.mark.parametrize(
    ("f", "limit"),
    [
        (0.39, None),
        (0.4, 0.02),
        (80.0, 0.02),
        (1000.0, 0.02),
        (1000.5, 0.04),
        (2000.0, 0.04),
        (2000.5, 0.06),
        (10000.0, 0.06),
        (10000.5, None),
        (12000.0, None),
        (0.0, None),
    ],
)
def test_iso_limit_boundaries(f: float, limit: float | None) -> None:
    assert iso_16063_21_limit(f) == limit


@pytest.mark.parametrize(
    ("f", "u", "verdict"),
    [
        (80.0, 0.019, Verdict.WITHIN),
        (80.0, 0.02, Verdict.WITHIN),
        (80.0, 0.021, Verdict.OVER),
        (1250.0, 0.03, Verdict.WITHIN),
        (1250.0, 0.05, Verdict.OVER),
        (4000.0, 0.05, Verdict.WITHIN),
        (4000.0, 0.07, Verdict.OVER),
        (12000.0, 0.5, Verdict.NOT_APPLICABLE),
        (0.2, 0.001, Verdict.NOT_APPLICABLE),
        (80.0, math.nan, Verdict.OVER),
        (80.0, math.inf, Verdict.OVER),
    ],
)
def test_iso_verdict(f: float, u: float, verdict: Verdict) -> None:
    assert iso_verdict(f, u) is verdict


def test_iso_refuses_nan_frequency_and_negative_uncertainty() -> None:
    with pytest.raises(ValueError, match="frequency_hz"):
        iso_16063_21_limit(math.nan)
    with pytest.raises(ValueError, match="relative_expanded_uncertainty"):
        iso_verdict(80.0, -0.01)


# --- properties ----------------------------------------------------------------------------

_dofs = st.one_of(st.floats(0.5, 1e4), st.just(math.inf))
_components = st.builds(
    Component,
    name=st.just("c"),
    value=st.floats(0.0, 1.0),
    distribution=st.sampled_from(list(Distribution)),
    coverage_factor=st.floats(0.5, 4.0),
    dof=_dofs,
)


@given(
    type_a=st.floats(0.0, 1.0),
    type_a_dof=_dofs,
    components=st.lists(_components, max_size=6),
    probability=st.floats(0.5, 0.999),
)
def test_combined_properties(
    type_a: float, type_a_dof: float, components: list[Component], probability: float
) -> None:
    res = combine(type_a, type_a_dof, Budget(tuple(components)), 100.0, probability=probability)
    u_bi = [c.standard_uncertainty for c in components]
    assert res.standard >= max([type_a, *u_bi]) * (1 - 1e-12)
    assert res.standard <= (type_a + sum(u_bi)) * (1 + 1e-12)
    assert res.standard == pytest.approx(math.hypot(type_a, res.type_b), rel=1e-12, abs=1e-300)
    if res.standard > 1e-300:  # subnormal floats carry too few digits for rel=1e-12
        assert res.expanded / res.standard == pytest.approx(res.coverage_factor, rel=1e-12)
    elif res.standard == 0.0:
        assert res.expanded == 0.0
    assert res.coverage_factor >= coverage_factor(math.inf, probability) * (1 - 1e-9)


@given(
    st.lists(
        st.tuples(st.floats(1e-6, 1e3), st.one_of(st.floats(0.5, 1e4), st.just(math.inf))),
        min_size=1,
        max_size=8,
    )
)
def test_welch_satterthwaite_bounds(pairs: list[tuple[float, float]]) -> None:
    # GUM G.4.1: with nonzero contributions, min nu_i <= nu_eff <= sum nu_i.
    u = [p[0] for p in pairs]
    nu = [p[1] for p in pairs]
    nu_eff = welch_satterthwaite(u, nu)
    assert nu_eff >= min(nu) * (1 - 1e-9)
    assert nu_eff <= sum(nu) * (1 + 1e-9)


# --- a budget computed by hand: every term counts (docs/mutation.md) ----------------------
#
# Magnitude at 160 Hz, u_i^2 in units of 1e-6 (relative^2):
#   type A                 u_A = 0.002, nu = 4                     u^2 =  4    u^4/nu = 4.0
#   reference calibration  normal U = 0.010, k = 2 -> u = 0.005    u^2 = 25    nu 50 -> 12.5
#   DAQ gain               rectangular a = 0.003 -> a^2/3          u^2 =  3
#   mounting               triangular a = 0.006 -> a^2/6           u^2 =  6
#   hum                    U-shaped a = 0.002 -> a^2/2             u^2 =  2
#   temperature            standard u = 0.001, nu = 10             u^2 =  1    nu 10 -> 0.1
#   (not applying: "upper band" from 1 kHz, "phase ref" a phase component)
#   u_B^2 = 37, u_c^2 = 41 -> u_c = sqrt(41e-6) = 0.0064031242...
#   nu_eff = 41^2 / (4.0 + 12.5 + 0.1) = 1681 / 16.6 = 101.265...
#   k = t_0.97725(101.27) = 2.025 (GUM table G.2: 2.025 at nu = 100), U = k u_c = 0.01297

HAND_TYPE_A = (0.002, 4.0)
HAND_U2 = {  # each term's u^2 in 1e-6, from the table above
    "reference calibration": 25.0,
    "DAQ gain": 3.0,
    "mounting": 6.0,
    "hum": 2.0,
    "temperature": 1.0,
}


def _hand_budget() -> Budget:
    return Budget(
        (
            Component("reference calibration", 0.010, Distribution.NORMAL, 2.0, dof=50),
            Component("DAQ gain", 0.003, Distribution.RECTANGULAR),
            Component("mounting", 0.006, Distribution.TRIANGULAR),
            Component("hum", 0.002, Distribution.U_SHAPED),
            Component("temperature", 0.001, Distribution.STANDARD, dof=10),
            Component("upper band", 0.05, min_frequency_hz=1000.0),
            Component("phase ref", 0.5, Distribution.STANDARD, quantity=Quantity.PHASE),
        )
    )


def test_hand_budget_combined_and_expanded() -> None:
    res = combine(*HAND_TYPE_A, _hand_budget(), 160.0)
    assert res.type_b == pytest.approx(math.sqrt(37e-6), rel=1e-12)
    assert res.standard == pytest.approx(math.sqrt(41e-6), rel=1e-12)  # 0.0064031...
    assert res.standard == pytest.approx(0.00640312424, rel=1e-9)
    assert res.dof == pytest.approx(1681 / 16.6, rel=1e-12)  # 101.265...
    assert res.coverage_factor == pytest.approx(2.025, abs=0.001)  # GUM table G.2, nu = 100
    assert res.coverage_factor == pytest.approx(stats.t.ppf(0.97725, 1681 / 16.6), rel=1e-12)
    assert res.coverage_probability == 0.9545
    assert res.expanded == pytest.approx(res.coverage_factor * math.sqrt(41e-6), rel=1e-12)
    assert res.expanded == pytest.approx(0.01297, abs=0.00001)
    u_b, nu_b = _hand_budget().type_b(160.0, MAG)
    assert u_b == pytest.approx(math.sqrt(37e-6), rel=1e-12)
    assert nu_b == pytest.approx(37**2 / 12.6, rel=1e-12)  # 1369 / (12.5 + 0.1)


@pytest.mark.parametrize("name", sorted(HAND_U2))
def test_every_hand_budget_term_counts(name: str) -> None:
    """The budget without `name` loses exactly that term's u^2: a combination that dropped,
    doubled or mis-divided any one term fails here."""
    comp = next(c for c in _hand_budget().components if c.name == name)
    assert comp.standard_uncertainty**2 == pytest.approx(HAND_U2[name] * 1e-6, rel=1e-12)
    without = Budget(tuple(c for c in _hand_budget().components if c.name != name))
    full = combine(*HAND_TYPE_A, _hand_budget(), 160.0)
    less = combine(*HAND_TYPE_A, without, 160.0)
    assert full.standard**2 - less.standard**2 == pytest.approx(HAND_U2[name] * 1e-6, rel=1e-9)
    assert less.standard == pytest.approx(math.sqrt((41.0 - HAND_U2[name]) * 1e-6), rel=1e-12)
    assert full.expanded > less.expanded


def test_hand_budget_above_1_khz_adds_the_upper_band_term() -> None:
    # upper band: rectangular a = 0.05 -> u^2 = 0.0025/3 = 833.33e-6; u_c^2 = 874.33e-6
    res = combine(*HAND_TYPE_A, _hand_budget(), 1000.0)
    assert res.standard == pytest.approx(math.sqrt(41e-6 + 0.0025 / 3), rel=1e-12)
    assert combine(*HAND_TYPE_A, _hand_budget(), 999.9).standard == pytest.approx(
        math.sqrt(41e-6), rel=1e-12
    )


def test_hand_budget_phase_uses_only_the_phase_term() -> None:
    # u_A 0.2 deg (nu 4), phase ref 0.5 deg: u_c^2 = 0.04 + 0.25 = 0.29 deg^2
    res = combine(0.2, 4, _hand_budget(), 160.0, PHASE)
    assert res.standard == pytest.approx(math.sqrt(0.29), rel=1e-12)
    assert res.dof == pytest.approx(0.29**2 / (0.2**4 / 4), rel=1e-12)  # 0.0841/0.0004 = 210.25
    assert res.dof == pytest.approx(210.25, rel=1e-12)


# --- error messages, word for word (they name the field and the component) -----------------

_KNOWN_KEYS = (
    "name, value, distribution, coverage_factor, dof, quantity, min_frequency_hz, "
    "max_frequency_hz, note, kind, law, law_frequency_hz, law_exponent"
)


@pytest.mark.parametrize(
    ("call", "error", "message"),
    [
        (lambda: Component("", 0.1), ValueError, "component '': name must be a non-empty string"),
        (
            lambda: Component("x", "a"),  # type: ignore[arg-type]
            ValueError,
            "component 'x': value must be a number, got 'a'",
        ),
        (
            lambda: Component("x", math.inf),
            ValueError,
            "component 'x': value must be finite, got inf",
        ),
        (lambda: Component("x", -0.1), ValueError, "component 'x': value must be >= 0, got -0.1"),
        (
            lambda: Component("x", 0.1, "gauss"),  # type: ignore[arg-type]
            ValueError,
            "component 'x': distribution must be one of 'normal', 'rectangular', 'triangular', "
            "'u-shaped', 'standard', got 'gauss'",
        ),
        (
            lambda: Component("x", 0.1, coverage_factor=0),
            ValueError,
            "component 'x': coverage_factor must be finite and > 0, got 0.0",
        ),
        (
            lambda: Component("x", 0.1, dof=0),
            ValueError,
            "component 'x': dof must be > 0 (inf allowed), got 0",
        ),
        (
            lambda: Component("x", 0.1, min_frequency_hz=-1),
            ValueError,
            "component 'x': min_frequency_hz must be finite and >= 0 Hz, got -1",
        ),
        (
            lambda: Component("x", 0.1, min_frequency_hz=10, max_frequency_hz=5),
            ValueError,
            "component 'x': min_frequency_hz must be <= max_frequency_hz, got 10.0 > 5.0",
        ),
        (
            lambda: Component("x", 0.1, note=3),  # type: ignore[arg-type]
            ValueError,
            "component 'x': note must be a string, got 3",
        ),
        (
            lambda: Component("x", 0.1).applies_at(math.nan),
            ValueError,
            "component 'x': frequency_hz must not be NaN",
        ),
        (
            lambda: Component("x", 0.1).applies_at("a"),  # type: ignore[arg-type]
            ValueError,
            "component 'x': frequency_hz must be a number, got 'a'",
        ),
        (
            lambda: Component.from_dict([1]),  # type: ignore[arg-type]
            ValueError,
            "component: expected a mapping of keys to values, got [1]",
        ),
        (
            lambda: Component.from_dict({"name": "x", "value": 0.1, "foo": 1}),
            ValueError,
            f"component 'x': unknown key 'foo' (known keys: {_KNOWN_KEYS})",
        ),
        (
            lambda: Component.from_dict({"value": 0.1}),
            ValueError,
            "component <unnamed>: missing key 'name'",
        ),
        (
            lambda: Component.from_dict({"name": "x"}),
            ValueError,
            "component 'x': missing key 'value'",
        ),
        (
            lambda: Component.from_dict({"name": "x", "value": 0.1, "dof": "many"}),
            ValueError,
            "component 'x': dof must be a number > 0, null or 'inf', got 'many'",
        ),
        (
            lambda: Budget((Component("x", 0.01), 5)),  # type: ignore[arg-type]
            TypeError,
            "budget entry 2: expected a Component, got 5",
        ),
        (
            lambda: Budget.from_list([{"name": "x", "value": 0.1}, {"name": "y"}]),
            ValueError,
            "budget entry 2 of 2: component 'y': missing key 'value'",
        ),
        (
            lambda: Budget().at(100.0, "volts"),  # type: ignore[arg-type]
            ValueError,
            "budget: quantity must be one of 'magnitude', 'phase', got 'volts'",
        ),
        (
            lambda: welch_satterthwaite([0.1], [1, 2]),
            ValueError,
            "welch_satterthwaite: standard_uncertainties and dofs must be 1-D and of equal "
            "length, got shapes (1,) and (2,)",
        ),
        (
            lambda: welch_satterthwaite([-0.1], [1]),
            ValueError,
            "welch_satterthwaite: uncertainties must be finite and >= 0, got [-0.1]",
        ),
        (
            lambda: welch_satterthwaite([0.1], [0]),
            ValueError,
            "welch_satterthwaite: dofs must be > 0 (inf allowed), got [0.]",
        ),
        (
            lambda: coverage_factor(5, 1.0),
            ValueError,
            "coverage_factor: probability must be in (0, 1), got 1.0",
        ),
        (
            lambda: coverage_factor(0),
            ValueError,
            "coverage_factor: dof must be > 0 (inf allowed), got 0",
        ),
        (
            lambda: seed_coverage_factor(True),
            ValueError,
            "seed_coverage_factor: periods must be an integer, got True",
        ),
        (
            lambda: seed_coverage_factor(2.5),  # type: ignore[arg-type]
            ValueError,
            "seed_coverage_factor: periods must be an integer, got 2.5",
        ),
        (
            lambda: seed_coverage_factor(1),
            ValueError,
            "seed_coverage_factor: periods must be >= 2, got 1",
        ),
        (
            lambda: combine(0.01, 3, Budget(), 100.0, rule="x"),
            ValueError,
            "combine: rule must be one of ('gum', 'seed'), got 'x'",
        ),
        (
            lambda: combine(0.01, 3, Budget(), 100.0, probability=0),
            ValueError,
            "combine: probability must be in (0, 1), got 0",
        ),
        (
            lambda: combine(0.01, 3, Budget(), 100.0, rule="seed"),
            ValueError,
            "combine: rule 'seed' needs periods (the number of periods L)",
        ),
        (
            lambda: combine(0.01, 3, None, 100.0),  # type: ignore[arg-type]
            TypeError,
            "combine: budget must be a Budget, got None",
        ),
        (
            lambda: combine(-1, 3, Budget(), 100.0),
            ValueError,
            "combine: type_a must be finite and >= 0 (or NaN), got -1",
        ),
        (
            lambda: combine(0.01, 0, Budget(), 100.0),
            ValueError,
            "combine: type_a_dof must be > 0 (inf allowed), got 0",
        ),
        (
            lambda: combine(0.01, 3, Budget(), 100.0, "volts"),  # type: ignore[arg-type]
            ValueError,
            "combine: quantity must be one of 'magnitude', 'phase', got 'volts'",
        ),
        (
            lambda: iso_16063_21_limit(math.nan),
            ValueError,
            "iso_16063_21_limit: frequency_hz must not be NaN",
        ),
        (
            lambda: iso_verdict(100.0, -0.1),
            ValueError,
            "iso_verdict: relative_expanded_uncertainty must be >= 0, got -0.1",
        ),
    ],
)
def test_error_messages_word_for_word(call, error, message) -> None:
    with pytest.raises(error) as info:
        call()
    assert str(info.value) == message


def test_component_defaults_include_an_empty_note() -> None:
    assert Component("x", 0.01).note == ""
    assert Component("x", 0.01).to_dict()["note"] == ""


def test_component_normalises_numbers_to_float_and_strings_to_enums() -> None:
    c = Component(
        "x",
        1,
        " Normal ",  # type: ignore[arg-type]
        coverage_factor=2,
        dof=10,
        quantity="PHASE",  # type: ignore[arg-type]
        min_frequency_hz=1,
        max_frequency_hz=2,
    )
    for field in ("value", "coverage_factor", "dof", "min_frequency_hz", "max_frequency_hz"):
        assert type(getattr(c, field)) is float, field
    assert c.distribution is Distribution.NORMAL
    assert c.quantity is Quantity.PHASE
    assert Budget((c,)).at(1.5, PHASE) == (c,)  # found by its enum, not its spelling
    assert c.to_dict() == {
        "name": "x",
        "value": 1.0,
        "distribution": "normal",
        "coverage_factor": 2.0,
        "dof": 10.0,
        "quantity": "phase",
        "min_frequency_hz": 1.0,
        "max_frequency_hz": 2.0,
        "note": "",
    }
    assert set(vars(c)) == {f.name for f in fields(Component)}  # no stray attributes


@pytest.mark.parametrize("lowest", [0.0, 0.4, 0.5])
def test_a_range_may_start_at_0_hz_or_below_1_hz(lowest: float) -> None:
    c = Component("low band", 0.01, min_frequency_hz=lowest, max_frequency_hz=lowest)
    assert c.min_frequency_hz == lowest
    assert c.applies_at(lowest)
    assert not c.applies_at(lowest + 0.01)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"coverage_factor": "2"}, "component 'x': coverage_factor must be a number, got '2'"),
        ({"dof": "10"}, "component 'x': dof must be a number, got '10'"),
        ({"max_frequency_hz": "1k"}, "component 'x': max_frequency_hz must be a number, got '1k'"),
        (
            {"max_frequency_hz": math.inf},
            "component 'x': max_frequency_hz must be finite and >= 0 Hz, got inf",
        ),
        (
            {"quantity": "volts"},
            "component 'x': quantity must be one of 'magnitude', 'phase', got 'volts'",
        ),
    ],
)
def test_component_field_errors_word_for_word(kwargs: dict, message: str) -> None:
    with pytest.raises(ValueError) as info:
        Component("x", 0.1, **kwargs)
    assert str(info.value) == message


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: coverage_factor("5"), "coverage_factor: dof must be a number, got '5'"),
        (
            lambda: coverage_factor(5, "0.95"),
            "coverage_factor: probability must be a number, got '0.95'",
        ),
        (
            lambda: combine("0.01", 3, Budget(), 100.0),
            "combine: type_a must be a number, got '0.01'",
        ),
        (
            lambda: combine(0.01, "3", Budget(), 100.0),
            "combine: type_a_dof must be a number, got '3'",
        ),
        (
            lambda: combine(0.01, 3, Budget(), 100.0, probability="x"),
            "combine: probability must be a number, got 'x'",
        ),
        (
            lambda: iso_verdict(100.0, "x"),
            "iso_verdict: relative_expanded_uncertainty must be a number, got 'x'",
        ),
        (
            lambda: iso_16063_21_limit("x"),
            "iso_16063_21_limit: frequency_hz must be a number, got 'x'",
        ),
    ],
)
def test_non_numbers_are_refused_by_function_and_argument(call, message) -> None:
    with pytest.raises(ValueError) as info:
        call()
    assert str(info.value) == message


@pytest.mark.parametrize("p", [0.0, 1.0, -0.5, 1.5])
def test_combine_refuses_probabilities_outside_the_open_interval(p: float) -> None:
    with pytest.raises(ValueError) as info:
        combine(0.01, 3, Budget(), 100.0, probability=p)
    assert str(info.value) == f"combine: probability must be in (0, 1), got {p!r}"


def test_combined_is_immutable() -> None:
    res = combine(*HAND_TYPE_A, _hand_budget(), 160.0)
    with pytest.raises(FrozenInstanceError):
        res.expanded = 0.0  # type: ignore[misc]


def test_zero_expanded_uncertainty_is_within_every_limit() -> None:
    for f in (0.4, 160.0, 1000.0, 1000.1, 2000.0, 10000.0):
        assert iso_verdict(f, 0.0) is Verdict.WITHIN


def test_welch_satterthwaite_single_component_keeps_its_dof() -> None:
    # nu_eff = u^4 / (u^4 / nu) = nu; with nu = 1 the denominator is exactly 1 (scaled)
    assert welch_satterthwaite([0.01], [1]) == pytest.approx(1.0, rel=1e-12)
    assert welch_satterthwaite([0.01, 0.01], [1, math.inf]) == pytest.approx(4.0, rel=1e-12)


@pytest.mark.parametrize("name", ["", 5])
def test_from_dict_without_a_usable_name_says_unnamed(name: object) -> None:
    with pytest.raises(ValueError) as info:
        Component.from_dict({"name": name, "value": 0.1, "foo": 1})
    assert str(info.value) == f"component <unnamed>: unknown key 'foo' (known keys: {_KNOWN_KEYS})"


@pytest.mark.parametrize("spelling", ["inf", "Infinity", " INF ", "infinity"])
def test_from_dict_spells_infinite_dof_both_ways(spelling: str) -> None:
    assert math.isinf(Component.from_dict({"name": "x", "value": 0.1, "dof": spelling}).dof)


def test_budget_is_a_frozen_tuple_of_components() -> None:
    c = Component("x", 0.01)
    b = Budget([c])  # type: ignore[arg-type]
    assert b.components == (c,) and type(b.components) is tuple
    assert Budget(c for c in [c]).components == (c,)  # type: ignore[arg-type]
    with pytest.raises(FrozenInstanceError):
        b.components = ()  # type: ignore[misc]


def test_seed_rectangular_notes_its_origin() -> None:
    (c,) = Budget.seed_rectangular({"DAQ": 0.05}).components
    assert c.note == "maximum permissible error (seed eq. 18/19)"
