"""A component stated as a table against frequency (dsp.budget_table): one value per band."""

from __future__ import annotations

import math

import pytest

from dsp.uncertainty import Budget, Quantity

ROWS = [[2500.0, 0.002], [5000.0, 0.009], [10000.0, 0.004]]


def _budget(**extra):
    entry = {"name": "rocking", "kind": "transverse_motion", "distribution": "standard"}
    return Budget.from_list([{**entry, "table": ROWS, **extra}])


def test_each_row_holds_over_its_band_and_only_there():
    budget = _budget(min_frequency_hz=2000.0)
    assert [c.name for c in budget.components] == [
        "rocking at 2500 Hz",
        "rocking at 5000 Hz",
        "rocking at 10000 Hz",
    ]
    edge = math.sqrt(2500.0 * 5000.0)  # 3535.5 Hz: the geometric mean of the rows
    for f, expected in (
        (2000.0, 0.002),
        (3535.0, 0.002),
        (edge, 0.009),
        (5000.0, 0.009),
        (7071.0, 0.009),
        (10000.0, 0.004),
        (10000.0 * math.sqrt(2.0), 0.004),  # a half step above the last row
    ):
        found = budget.at(f, Quantity.MAGNITUDE)
        assert [c.standard_uncertainty for c in found] == [pytest.approx(expected)], f
        assert found[0].kind[0].value == "transverse_motion"
    assert budget.at(1999.0, Quantity.MAGNITUDE) == ()  # below the first band's edge
    assert budget.at(14143.0, Quantity.MAGNITUDE) == ()  # above the last band's


def test_a_rectangular_table_reads_half_widths():
    budget = _budget(distribution="rectangular")
    (c,) = budget.at(5000.0, Quantity.MAGNITUDE)
    assert c.standard_uncertainty == pytest.approx(0.009 / math.sqrt(3.0))


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        ({"value": 0.001}, "either value or table"),
        ({"law": "power", "law_frequency_hz": 1.0}, "law does not go with a table"),
        ({"table": []}, "non-empty list"),
        ({"table": [[1000.0, 0.1], [900.0, 0.1]]}, "row 2: frequencies must rise"),
        ({"table": [[1000.0]]}, "row 1 must be [frequency_hz, value]"),
        ({"table": [[0.0, 0.1]]}, "row 1: frequency must be finite and > 0 Hz"),
        ({"table": [[1000.0, -0.1]]}, "value must be >= 0"),
        ({"min_frequency_hz": 3000.0}, "must lie outside the table's rows"),
    ],
)
def test_a_bad_table_is_refused_naming_the_entry_and_why(extra, message):
    with pytest.raises(ValueError, match="budget entry 1 of 1") as caught:
        _budget(**extra)
    assert message in str(caught.value) and "rocking" in str(caught.value)
