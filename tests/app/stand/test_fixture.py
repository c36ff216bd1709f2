"""The stand file's fixture (issue 36): [fixture] and [[fixture.position]] read into typed
positions, their inputs from [daq.dut], the stated terms as budget components, the mass limits,
and every refusal naming its key."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from app.stand import config as stand_config
from app.stand.config import ConfigError
from app.stand.fixture import MotionTable
from hardware.errors import InputRefused
from hardware.interfaces import DaqConfig, InputChannel, OutputChannel, is_dut_channel

FIXTURE4 = Path(__file__).parents[3] / "sim" / "stand-fixture4.toml"
BASE = (Path(__file__).parents[3] / "sim" / "stand.toml").read_text(encoding="utf-8")


def _with_fixture(fixture: str) -> stand_config.StandConfig:
    return stand_config.parse(BASE + "\n" + fixture, "test.toml")


POSITION_A = """
[fixture]
name = "block"
mass_kg = 0.1
mass_limit_kg = 0.3
crosstalk_db = -80.0

[[fixture.position]]
name = "A"
physical = "sim/ai1"
distance_mm = 10.0
mass_limit_kg = 0.05
relative_motion = [[10.0, 0.01], [1000.0, 0.05], [10000.0, 1.0]]
"""


def test_the_example_stand_has_four_positions_with_dut_inputs() -> None:
    config = stand_config.load(FIXTURE4)
    fixture = config.fixture
    assert fixture is not None and fixture.mass_kg == 0.120 and fixture.mass_limit_kg == 0.400
    assert [p.name for p in fixture.positions] == ["A", "B", "C", "D"]
    dut = next(c for c in config.inputs if c.name == "dut")
    inputs = fixture.inputs(dut)
    assert [c.name for c in inputs] == ["dut.A", "dut.B", "dut.C", "dut.D"]
    assert [c.physical for c in inputs] == ["sim/ai1", "sim/ai3", "sim/ai4", "sim/ai5"]
    # [daq.dut]'s settings on every position's input
    assert all(c.range_v == dut.range_v and c.coupling == "ac" for c in inputs)
    assert all(c.iepe_current_a == dut.iepe_current_a for c in inputs)
    # a single-DUT stand's inputs as before
    assert [c.name for c in config.inputs] == ["reference", "dut", "drive"]


def test_a_stand_without_fixture_has_none() -> None:
    assert stand_config.parse(BASE, "test.toml").fixture is None


def test_a_triaxial_position_has_three_named_inputs() -> None:
    config = _with_fixture(
        POSITION_A
        + """
[[fixture.position]]
name = "T"
axes = { x = "sim/ai4", y = "sim/ai5", z = "sim/ai6" }
"""
    )
    assert config.fixture is not None
    position = config.fixture.position("T")
    assert position.channels == ("dut.T.x", "dut.T.y", "dut.T.z")
    dut = next(c for c in config.inputs if c.name == "dut")
    assert [c.physical for c in position.inputs(dut)] == ["sim/ai4", "sim/ai5", "sim/ai6"]
    assert all(is_dut_channel(name) for name in position.channels)


@pytest.mark.parametrize(
    ("extra", "named"),
    [
        ('[fixture]\nname = "x"\nmas_kg = 1\n', "fixture.mas_kg"),
        ('[fixture]\nname = "x"\n', "fixture.position"),
        (POSITION_A.replace('name = "A"', 'name = "A B"'), "fixture.position[0].name"),
        (POSITION_A + '[[fixture.position]]\nname = "A"\nphysical = "sim/ai5"\n', "named twice"),
        (POSITION_A.replace("sim/ai1", "sim/ai2"), "also the drive input"),
        (POSITION_A.replace('physical = "sim/ai1"', ""), "give either physical"),
        (
            POSITION_A.replace("[1000.0, 0.05]", "[5.0, 0.05]"),
            "relative_motion[1]: frequencies must rise",
        ),
        (POSITION_A.replace("-80.0", "3.0"), "fixture.crosstalk_db"),
        (POSITION_A.replace("mass_limit_kg = 0.05", "mass_limit_kg = -1"), "mass_limit_kg"),
        (POSITION_A.replace("distance_mm = 10.0", 'distance_mm = "far"'), "distance_mm"),
        (POSITION_A.replace("[10.0, 0.01],", "[10.0],"), "relative_motion[0]"),
        (
            POSITION_A
            + '[[fixture.position]]\nname = "T"\nskew_s = 8e-6\n'
            + 'axes = { x = "sim/ai4", y = "sim/ai5", z = "sim/ai6" }\n',
            "fixture.position 'T'.skew_s: a triaxial position",
        ),
    ],
)
def test_a_fixture_that_cannot_be_used_is_refused_naming_the_key(extra: str, named: str) -> None:
    with pytest.raises(ConfigError, match=r"test\.toml") as exc:
        _with_fixture(extra)
    assert named in str(exc.value)


def test_the_relative_motion_is_log_log_interpolated_and_flat_outside() -> None:
    table = MotionTable(((10.0, 0.01), (1000.0, 0.05), (10000.0, 1.0)))
    assert table.at(1.0) == 0.01 and table.at(50000.0) == 1.0
    assert table.at(1000.0) == pytest.approx(0.05)
    # the geometric mean of the frequencies gives the geometric mean of the values
    assert table.at(100.0) == pytest.approx(math.sqrt(0.01 * 0.05), rel=1e-12)
    assert table.at(math.sqrt(1e7)) == pytest.approx(math.sqrt(0.05 * 1.0), rel=1e-12)


@pytest.mark.parametrize("frequency_hz", [1.0, 10.0, 63.0, 999.9, 1000.0, 3150.0, 10000.0, 2e4])
def test_the_budget_states_the_table_once_at_every_frequency(frequency_hz: float) -> None:
    config = _with_fixture(POSITION_A)
    assert config.fixture is not None
    position = config.fixture.position("A")
    budget = position.budget(-80.0, 2.0)
    magnitude = [c for c in budget.at(frequency_hz, "magnitude") if "relative motion" in c.name]
    assert len(magnitude) == 1  # segments end just below the next point: none counted twice
    u = magnitude[0].standard_uncertainty_at(frequency_hz)
    assert u == pytest.approx(position.relative_motion.at(frequency_hz) / 100, rel=1e-9)
    crosstalk = [c for c in budget.at(frequency_hz, "magnitude") if "crosstalk" in c.name]
    assert [c.standard_uncertainty for c in crosstalk] == [pytest.approx(2e-4, rel=1e-12)]
    assert all(position.owns(c.name) for c in budget.components)


def test_a_position_owns_only_its_own_terms() -> None:
    config = _with_fixture(
        POSITION_A + '[[fixture.position]]\nname = "AB"\nphysical = "sim/ai5"\n'
        "relative_motion = [[10.0, 0.02]]\n"
    )
    assert config.fixture is not None
    a, ab = config.fixture.position("A"), config.fixture.position("AB")
    assert not any(a.owns(c.name) for c in ab.budget(-80.0).components)
    assert not any(ab.owns(c.name) for c in a.budget(-80.0).components)


def test_the_mass_limits_name_the_fixture_and_the_position() -> None:
    config = _with_fixture(POSITION_A)
    assert config.fixture is not None
    assert config.fixture.mass_problems({"A": 0.04}) == []
    (position,) = config.fixture.mass_problems({"A": 0.06})
    assert "fixture.position 'A' mass_limit_kg" in position
    assert any("fixture.mass_limit_kg" in p for p in config.fixture.mass_problems({"A": 0.31}))


def test_the_iso_limit_check_names_the_lines_the_stated_motion_alone_exceeds() -> None:
    config = _with_fixture(POSITION_A)
    assert config.fixture is not None
    position = config.fixture.position("A")
    # 2 x 1 % = 2 % at 10 kHz: within its band's 6 %; from 1 kHz to 2 kHz the limit is 4 %
    assert position.over_limit_hz([160.0, 1000.0, 8000.0, 10000.0]) == []
    loud = _with_fixture(POSITION_A.replace("[10000.0, 1.0]", "[10000.0, 5.0]")).fixture
    assert loud is not None
    assert loud.position("A").over_limit_hz([160.0, 8000.0, 10000.0]) == [8000.0, 10000.0]
    # the plan with lines the motion leaves alone: a warning naming the others
    assert position.limit_check([160.0, 10000.0]) == (None, ())
    refusal, warnings = loud.position("A").limit_check([160.0, 8000.0, 10000.0])
    assert refusal is None
    assert warnings == (
        "fixture position A: its stated relative motion alone exceeds the ISO 16063-21 limit "
        "at 8000, 10000 Hz",
    )
    # every line of the plan over: refused, no warnings
    refusal, warnings = loud.position("A").limit_check([8000.0, 10000.0])
    assert warnings == () and refusal is not None
    assert "fixture.position 'A' relative_motion" in refusal and "every line" in refusal


def test_the_daq_needs_a_reference_and_a_dut_channel_of_either_kind() -> None:
    output = OutputChannel("ao0", 10.0)
    ref = InputChannel("reference", "ai0", 1.0)
    DaqConfig(1000.0, 100, output, (ref, InputChannel("dut.A", "ai1", 1.0)))
    DaqConfig(1000.0, 100, output, (ref, InputChannel("dut", "ai1", 1.0)))
    with pytest.raises(InputRefused, match="at least one DUT input channel"):
        DaqConfig(1000.0, 100, output, (ref, InputChannel("dutA", "ai1", 1.0)))
    with pytest.raises(InputRefused, match="unique"):
        DaqConfig(
            1000.0, 100, output, (ref, InputChannel("dut.A", "ai1", 1.0),
                                  InputChannel("dut.A", "ai2", 1.0))
        )  # fmt: skip
    assert [is_dut_channel(n) for n in ("dut", "dut.A", "dut.T.x", "dut.", "dut.A.B.C")] == [
        True, True, True, False, False
    ]  # fmt: skip
