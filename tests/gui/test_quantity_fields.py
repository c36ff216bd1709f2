"""The Setup tab's quantity fields take what the command line takes (issue 31 point 3): level,
nominal sensitivity, tolerance and type A target with their units (`0.5g`, `100mV/g`, `0.2%`)
or as bare numbers in the field's unit, read by the same parser; a refused text is marked at
its field with the reason, Start stays disabled, and no run is built from it."""

from __future__ import annotations

import os
import re

import pytest

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

from app.gui.main_window import MainWindow
from app.gui.quantity_edit import QuantityEdit
from app.io import quantities
from app.io.quantities import QuantityError


@pytest.fixture()
def setup(qtbot, tmp_path):
    w = MainWindow(out=tmp_path / "runs", paced=False, seed=4)
    qtbot.addWidget(w)
    w.wait_for_plans()
    return w.setup_tab


def _type(qtbot, field: QuantityEdit, text: str) -> None:
    """Type `text` over the field's text as a technician does."""
    field.selectAll()
    field.del_()
    qtbot.keyClicks(field, text)
    assert field.text() == text


def test_the_fields_take_units_and_the_run_gets_the_values_in_its_own(setup, qtbot):
    _type(qtbot, setup.level, "0.5g")
    _type(qtbot, setup.nominal, "100mV/g")
    _type(qtbot, setup.tolerance, "2.5%")
    _type(qtbot, setup.target, "0.2")  # a bare number is percent: 0.2 %, never 20 %
    setup.wait_for_plans()
    assert setup.field_marks.marked() == {}
    assert setup.start_button.isEnabled(), setup.start_button.toolTip()
    assert setup.level.value() == pytest.approx(4.903325, rel=1e-12)
    assert setup.level.suffix().strip() == "= 4.903 m/s²"  # the typed value in the field's unit
    request = setup.request()
    assert request.level_ms2 == pytest.approx(4.903325, rel=1e-12)
    assert request.target_type_a == pytest.approx(0.002, rel=1e-12)
    options = setup.run_options()
    assert options.nominal_mv_per_ms2 == pytest.approx(10.197162129779283, rel=1e-12)
    assert options.tolerance_percent == 2.5
    _type(qtbot, setup.target, "0.2%")
    assert setup.request().target_type_a == pytest.approx(0.002, rel=1e-12)


@pytest.mark.parametrize(
    ("name", "text", "reason"),
    [
        ("level", "g/s", "level: 'g/s' is not an acceleration (m/s^2 or g)"),
        ("level", "0.5gg", "level: '0.5gg' is not an acceleration (m/s^2 or g): unknown unit"),
        ("level", "-1", "level: must be in (0, 1000] m/s^2"),
        ("level", "nan", "level: must be a finite number"),
        ("nominal", "10 pC/(m/s^2)", "is a charge sensitivity"),
        ("tolerance", "5 m", "tolerance: '5 m' is not a percentage"),
        ("target", "0.2 g", "type A target: '0.2 g' is not a percentage"),
        ("target", "150", "type A target: must be in (0, 100] %"),
    ],
)
def test_a_refused_text_is_marked_with_its_reason_and_start_waits(setup, qtbot, name, text, reason):
    field = getattr(setup, name)
    before = field.value()
    field.setText(text)  # pasted: typing it would pass through readable texts ("0.5g")
    assert field.error() is not None and reason in field.error()
    shown = setup.field_marks.reason(field).replace("&#x27;", "'")
    assert reason.replace("m/s^2", "m/s²") in shown
    assert list(setup.field_marks.marked()) == [name]
    assert not setup.start_button.isEnabled()
    assert reason in setup.start_button.toolTip()
    assert field.value() == before  # the last value read stays; no run is built from it
    with pytest.raises(QuantityError, match=re.escape(reason)):
        setup.request()
    _type(qtbot, field, f"{before:g}")  # put right: the mark goes, Start comes back
    setup.wait_for_plans()
    assert setup.field_marks.marked() == {} and setup.start_button.isEnabled()


def test_the_gui_reads_what_the_cli_reads(setup, qtbot):
    """Each text gives the field the value `accelcal run` gives its option."""
    from app.cli import build_parser

    cases = [
        ("level", "--level", "0.5 gn"),
        ("level", "--level", "7.5 m/s^2"),
        ("nominal", "--nominal-sensitivity", "0.1 V/g"),
        ("tolerance", "--tolerance", "5"),
    ]
    for name, option, text in cases:
        _type(qtbot, getattr(setup, name), text)
        cli = getattr(
            build_parser().parse_args(["run", option, text]),
            name.replace("nominal", "nominal_sensitivity"),
        )
        assert getattr(setup, name).value() == cli, (name, text)
    _type(qtbot, setup.target, "0.5")
    assert setup.request().target_type_a == quantities.parse_percent("0.5", "--target-ua") / 100


def test_blank_fields_mean_not_given_and_a_set_value_is_kept_exactly(setup, qtbot):
    _type(qtbot, setup.nominal, "")
    _type(qtbot, setup.target, "0")  # 0 is "off", as the spin box's 0 was
    assert setup.nominal.error() is None and setup.target.error() is None
    assert setup.run_options().nominal_mv_per_ms2 is None
    assert setup.request().target_type_a is None
    setup.nominal.setValue(100 / 9.80665)  # as a sensor on record fills it
    assert setup.nominal.text() == "10.1972"  # shown to 6 digits
    assert setup.nominal.value() == 100 / 9.80665  # kept exactly
    _type(qtbot, setup.level, "")
    assert "level: empty" in (setup.level.error() or "")  # the level has no "not given"


def test_the_window_opens_without_the_units_library(tmp_path):
    """pint is imported the first time a unit is typed, not when the window opens."""
    import subprocess
    import sys

    code = (
        "import sys; from PySide6.QtWidgets import QApplication; app = QApplication([]); "
        "from app.gui.main_window import MainWindow; "
        f"w = MainWindow(out={str(tmp_path / 'runs')!r}, paced=False); "
        "w.setup_tab.level.setText('7.5'); assert w.setup_tab.level.value() == 7.5; "
        "print('pint' in sys.modules); w.close_pools() if hasattr(w, 'close_pools') else None"
    )
    env = {**os.environ, "QT_QPA_PLATFORM": "offscreen"}
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip().splitlines()[-1] == "False"
