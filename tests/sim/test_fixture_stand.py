"""The simulated stand with several DUTs on a fixture (issue 36): each position's DUT its own
sensor model, the motion at a position the reference axis's times the fixture's motion ratio,
the crosstalk mixing the inputs; the rigid fixture the default (sim.fixture_rigid)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pytest

from hardware.interfaces import DaqConfig, InputChannel, OutputChannel
from sim.fixture_rigid import FixtureMotion, RigidFixture, fixture_motion
from sim.fixture_stand import FixtureStand

FS, N, LINE = 12800.0, 12800, 160  # 1 Hz bins: the line at bin 160


def _config(channels: Sequence[str]) -> DaqConfig:
    inputs = [InputChannel("reference", "ai0", 10.0)]
    inputs += [InputChannel(name, f"ai{i + 1}", 10.0) for i, name in enumerate(channels)]
    return DaqConfig(FS, N, OutputChannel("ao0", 10.0), tuple(inputs))


def _line(stand: FixtureStand, channels: Sequence[str]) -> np.ndarray:
    """Complex amplitude at the line on every input, in the steady state."""
    stand.configure(_config(channels))
    t = np.arange(N) / FS
    stand.start(0.002 * np.sin(2 * np.pi * LINE * t))
    for _ in range(3):
        block = stand.read_period()
    return np.fft.rfft(block, axis=1)[:, LINE]


class Tilted:
    """A fixture whose position B moves 1.1 times (and 2 deg ahead of) the reference axis,
    with channel dut.A leaking 1 % into dut.B."""

    def motion_ratio(self, position: str, frequency_hz: np.ndarray) -> np.ndarray:
        ratio = 1.1 * np.exp(1j * np.radians(2.0)) if position == "B" else 1.0
        return np.full(np.shape(frequency_hz), ratio, dtype=complex)

    def crosstalk(self, frequency_hz: np.ndarray, channels: Sequence[str]) -> np.ndarray:
        mix = RigidFixture().crosstalk(frequency_hz, channels)
        names = list(channels)
        if "dut.A" in names and "dut.B" in names:
            mix[:, names.index("dut.B"), names.index("dut.A")] = 0.01
        return mix


def test_the_rigid_fixture_is_the_default_and_the_protocol_holds() -> None:
    assert isinstance(fixture_motion({}), RigidFixture)
    assert isinstance(Tilted(), FixtureMotion) and isinstance(RigidFixture(), FixtureMotion)
    f = np.array([1.0, 100.0])
    assert np.array_equal(RigidFixture().motion_ratio("A", f), np.ones(2))
    assert RigidFixture().crosstalk(f, ["a", "b"]).shape == (2, 2, 2)


def test_each_position_reads_its_own_sensor_model() -> None:
    channels = ["dut.A", "dut.B"]
    stand = FixtureStand({"dut.A": "piezo", "dut.B": "capacitive"}, seed=3, systematic=False)
    lines = _line(stand, channels)
    ratio = lines[2] / lines[1]  # B over A: the two sensors' sensitivities at the line
    f = np.array([float(LINE)])
    truth = stand.truth_of("dut.B").sensitivity(f)[0] / stand.truth_of("dut.A").sensitivity(f)[0]
    assert abs(ratio) == pytest.approx(abs(truth), rel=2e-3)
    assert abs(abs(truth) - 1) > 0.1  # the two models differ: a mix-up would show


def test_the_motion_ratio_and_the_crosstalk_reach_the_channels() -> None:
    channels = ["dut.A", "dut.B"]
    rigid = _line(
        FixtureStand({"dut.A": "piezo", "dut.B": "piezo"}, seed=3, systematic=False), channels
    )
    tilted = _line(
        FixtureStand(
            {"dut.A": "piezo", "dut.B": "piezo"}, seed=3, systematic=False, fixture=Tilted()
        ),
        channels,
    )
    assert tilted[1] == pytest.approx(rigid[1], rel=1e-4)  # A moves with the reference axis
    expected_b = rigid[2] * 1.1 * np.exp(1j * np.radians(2.0)) + 0.01 * rigid[1]
    assert abs(tilted[2] / expected_b - 1) < 2e-4
    assert tilted[0] == pytest.approx(rigid[0], rel=1e-6)  # the reference is untouched


def test_the_exciter_carries_every_dut_and_the_fixture() -> None:
    one = _line(FixtureStand({"dut.A": "piezo"}, seed=3, systematic=False), ["dut.A"])
    heavy = _line(
        FixtureStand({"dut.A": "piezo"}, seed=3, systematic=False, fixture_mass_g=2000.0),
        ["dut.A"],
    )
    assert abs(heavy[0]) < 0.99 * abs(one[0])  # the same drive moves a heavier load less


def test_a_fixture_stand_refuses_a_channel_that_is_not_a_position() -> None:
    with pytest.raises(ValueError, match=r"dut\.<position>"):
        FixtureStand({"dut": "piezo"})
    with pytest.raises(ValueError, match="catalogue"):
        FixtureStand({"dut.A": "nothing"})


def test_the_stand_files_fixture_physics_is_wired_in_its_one_place() -> None:
    import tomllib
    from pathlib import Path

    from hardware.errors import InputRefused
    from sim.fixture import FixtureModel

    root = Path(__file__).parents[2] / "sim"
    rigid = tomllib.loads((root / "stand-fixture4.toml").read_text(encoding="utf-8"))
    assert isinstance(fixture_motion(rigid), RigidFixture)  # no [simulation.fixture]
    tables = tomllib.loads((root / "stand-fixture4-physics.toml").read_text(encoding="utf-8"))
    model = fixture_motion(tables)
    assert isinstance(model, FixtureModel)
    f = np.array([160.0, 11200.0])
    assert abs(model.motion_ratio("A", f)[0] - 1) < 1e-4  # on the axis, far below the modes
    assert abs(abs(model.motion_ratio("D", f)[1]) - 1) > 1e-3  # off axis, near a rocking mode
    tables["simulation"]["fixture"]["rocking_hx"] = 1.0
    with pytest.raises(InputRefused, match="rocking_hx"):
        fixture_motion(tables)
