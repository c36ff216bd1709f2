"""A quantity typed in its working unit (`0.2%`, `160 Hz`) is read without building pint's
registry (issue 34: it costs more than a run's start-up budget), to the value pint gives."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import pytest

from app.io import quantities as q

ROOT = Path(__file__).resolve().parents[3]
DIMENSIONS = (q.ACCELERATION, q.SENSITIVITY, q.TIME, q.FREQUENCY, q.MASS, q.PERCENT)


@pytest.mark.parametrize("dimension", DIMENSIONS, ids=lambda d: d.shown)
def test_the_working_unit_reads_as_pint_reads_it(dimension: q.Dimension) -> None:
    ureg = q.registry()
    for number in ("0.2", "1", "160", "1e-3", "-3", "+2.5", ".5", "0", "7.3e5"):
        for space in ("", " "):
            text = f"{number}{space}{dimension.shown}"
            unit = q._unit(dimension.shown, "--x", dimension, text)
            by_pint = float(ureg.Quantity(float(number), unit).to(dimension.unit).magnitude)
            value = q.to_unit(text, "--x", dimension)
            assert value == by_pint and math.copysign(1, value) == math.copysign(1, by_pint)


def test_the_working_unit_does_not_import_pint_and_other_units_still_do() -> None:
    code = (
        "import sys\nfrom app.io import quantities as q\n"
        "assert q.to_unit('0.2%', '--target-ua', q.PERCENT) == 0.2\n"
        "assert q.to_unit('160 Hz', '--f', q.FREQUENCY) == 160.0\n"
        "assert 'pint' not in sys.modules\n"
        "assert q.to_unit('2 kHz', '--f', q.FREQUENCY) == 2000.0\n"
        "assert 'pint' in sys.modules\n"
    )
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr


def test_a_working_unit_out_of_range_or_infinite_is_still_refused() -> None:
    with pytest.raises(q.QuantityError, match="--target-ua"):
        q.to_unit("inf%", "--target-ua", q.PERCENT)
