"""app/formatting.py against expected strings written by hand (docs/mutation.md).

GUM 7.2.6 as the project states it: the expanded uncertainty U to two significant digits, the
value rounded at the same decimal place. Ties are rounded away from zero on the decimal that
prints as the number (9.95 -> 10, 1.25e-05 -> 1.3e-05, 0.125 -> 0.13), whatever side of the
tie the binary double falls on; a U that rounds up to a new digit (0.0995 -> 0.100) keeps two
significant digits (0.10).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from app.formatting import percent, round_gum, signed, significant, table

NAN, INF = math.nan, math.inf


@pytest.mark.parametrize(
    ("value", "uncertainty", "expected"),
    [
        # ordinary: U 0.0123 -> 0.012, place 0.001; -3.14159 -> -3.142
        (-3.14159, 0.0123, ("-3.142", "0.012")),
        (3.14159, 0.0123, ("3.142", "0.012")),
        (9.2134, 0.0994, ("9.213", "0.099")),
        # U 0.0995 -> 0.100 has three digits: one place less -> 0.10, value 9.21
        (9.2134, 0.0995, ("9.21", "0.10")),
        (9.87, 0.0996, ("9.87", "0.10")),
        (-9.87, 0.0996, ("-9.87", "0.10")),
        # U 9.95 (a tie; the double is 9.9499999...) -> 10, value at the units: 9
        (9.21, 9.95, ("9", "10")),
        (-9.21, 9.95, ("-9", "10")),
        # U 99.5 -> 100 -> two digits at the tens: 1.0e2, value 42 -> 40
        (42.0, 99.5, ("40", "100")),
        # U 1.25e-05 (a tie; the double is just above) -> 0.000013, place 1e-6
        (0.00123456, 1.25e-5, ("0.001235", "0.000013")),
        (-0.00123456, 1.25e-5, ("-0.001235", "0.000013")),
        # trailing zeros kept on both
        (12.3, 0.25, ("12.30", "0.25")),
        (0.0, 0.5, ("0.00", "0.50")),
        (1.0, 1.0, ("1.0", "1.0")),
        (-0.004, 0.05, ("-0.004", "0.050")),
        # a value that rounds to zero is "0.000", never "-0.000"
        (-0.0004, 0.05, ("0.000", "0.050")),
        # value ties at the place of U, away from zero (0.125 is an exact binary tie)
        (0.125, 0.25, ("0.13", "0.25")),
        (-0.125, 0.25, ("-0.13", "0.25")),
        (2.45, 1.5, ("2.5", "1.5")),
        # U above 10: the value is rounded left of the decimal point
        (123456.0, 1234.0, ("123500", "1200")),
        (-123456.0, 1234.0, ("-123500", "1200")),
        (9.21, 34.0, ("9", "34")),
        # a large value with a small U keeps every digit (no float noise)
        (1e15, 0.25, ("1000000000000000.00", "0.25")),
        # numpy scalars (what the estimators return) behave like floats
        (np.float64(9.2134), np.float64(0.0995), ("9.21", "0.10")),
        # no usable U: the value to 4 significant digits, U "n/a"
        (9.2134, 0.0, ("9.213", "n/a")),
        (9.2134, -0.1, ("9.213", "n/a")),
        (9.2134, NAN, ("9.213", "n/a")),
        (9.2134, INF, ("9.213", "n/a")),
        (123456.0, NAN, ("1.235e+05", "n/a")),
        (NAN, 0.1, ("n/a", "n/a")),
        (INF, 0.1, ("n/a", "n/a")),
        (-INF, NAN, ("n/a", "n/a")),
    ],
)
def test_round_gum(value, uncertainty, expected):
    assert round_gum(value, uncertainty) == expected


@pytest.mark.parametrize(
    ("value", "uncertainty", "digits", "expected"),
    [
        (9.2134, 0.034, 1, ("9.21", "0.03")),
        (9.2134, 0.096, 1, ("9.2", "0.1")),  # 0.096 -> 0.10 -> one digit: 0.1
        (9.213449, 0.012345, 3, ("9.2134", "0.0123")),
        (9.213449, 0.09996, 3, ("9.213", "0.100")),  # 0.09996 -> 0.1000 -> 0.100, place 0.001
    ],
)
def test_round_gum_other_digit_counts(value, uncertainty, digits, expected):
    assert round_gum(value, uncertainty, digits) == expected


@pytest.mark.parametrize(
    ("value", "expected"),
    [
        (0.8, "0.80"),
        (1.234, "1.2"),
        (12.3, "12"),
        (123.4, "123"),  # never rounded left of the decimal point
        (-0.0456, "-0.046"),
        (9.94, "9.9"),
        (9.96, "10"),  # rounds up to a new digit: two significant digits, not 10.0
        (0.0995, "0.10"),  # not 0.100
        (-9.96, "-10"),
        (99.6, "100"),
        (0.125, "0.13"),  # exact binary tie, away from zero
        (0.135, "0.14"),
        (np.float64(0.0995), "0.10"),
        (0.0, "0"),
        (NAN, "n/a"),
        (INF, "n/a"),
        (-INF, "n/a"),
    ],
)
def test_significant(value, expected):
    assert significant(value) == expected


@pytest.mark.parametrize(
    ("value", "digits", "expected"),
    [(1.2345, 3, "1.23"), (0.0012345, 1, "0.001"), (0.0012345, 4, "0.001235"), (7.0, 1, "7")],
)
def test_significant_other_digit_counts(value, digits, expected):
    assert significant(value, digits) == expected


@pytest.mark.parametrize(
    ("value", "decimals", "expected"),
    [
        (0.123, 2, "+0.12"),
        (-0.05, 2, "-0.05"),
        (-0.004, 2, "0.00"),  # not "-0.00"
        (0.004, 2, "0.00"),  # not "+0.00"
        (-0.006, 2, "-0.01"),
        (1.5, 1, "+1.5"),
        (0.0, 3, "0.000"),
        (12.0, 0, "+12"),
    ],
)
def test_signed(value, decimals, expected):
    assert signed(value, decimals) == expected


@pytest.mark.parametrize(
    ("ratio", "decimals", "expected"),
    [
        (0.0123, 2, "1.23 %"),
        (0.0123, 1, "1.2 %"),
        (-0.005, 2, "-0.50 %"),
        (1.0, 0, "100 %"),
        (NAN, 2, "n/a"),
        (INF, 2, "n/a"),
    ],
)
def test_percent(ratio, decimals, expected):
    assert percent(ratio, decimals) == expected


def test_percent_default_two_decimals():
    assert percent(0.0123) == "1.23 %"


def test_table_right_aligns_to_the_widest_cell():
    text = table(["f", "S"], [["10", "9.21"], ["1000", "9.3"]])
    assert text == "   f     S\n----  ----\n  10  9.21\n1000   9.3"


def test_table_header_wider_than_cells_and_no_rows():
    assert table(["freq", "S"], [["1", "22"]]) == "freq   S\n----  --\n   1  22"
    assert table(["a", "bb"], []) == "a  bb\n-  --"


def test_table_refuses_a_row_of_the_wrong_length():
    with pytest.raises((ValueError, IndexError)):
        table(["a", "b"], [["1", "2", "3"]])


def test_the_resonance_is_stated_with_its_u_or_not_found_within_the_plan():
    """Issue 32 point 5: f0 and Q with their U rounded per GUM; an unbracketed peak is
    "not found within the plan" with the reason; nothing searched says so."""
    import numpy as np

    from app.formatting import resonance_text
    from dsp.resonance import search_resonance

    f = np.arange(20000.0, 30001.0, 250.0)
    mode = 1 / (1 - (f / 25000.0) ** 2 + 1j * f / (25000.0 * 35.0))
    text = resonance_text(search_resonance(f, mode, np.full(f.size, 0.002)).to_dict())
    assert text.startswith("resonance: f0 = (25000") and "Q = 35" in text and "k = 2.00" in text
    assert " ± " in text.split("Q =")[0] and " ± " in text.split("Q =")[1]
    missed = resonance_text(search_resonance(f[:21], mode[:21]).to_dict())
    assert missed.startswith("resonance: not found within the plan: still rising")
    assert "mount" not in missed
    assert resonance_text(None) == "resonance: not searched (run with --resonance)"
