"""The simulated fixture's mountings (sim/fixture.py, issue 36 acceptance 1): a run's block drawn
from its seed, and the terms a lab states from its own mountings, against hand figures."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hardware.errors import InputRefused
from sim.fixture import FixtureModel, PositionGeometry, characterised_terms
from sim.fixture_stand import FixtureStand

TABLE = {
    "rocking_hz": [11_200.0, 12_800.0],
    "rocking_q": 25.0,
    "eccentricity_mm": 0.0,
    "gyration_radius_mm": 30.0,
    "crosstalk_db": -90.0,
    "crosstalk_flat_db": -106.0,
    "crosstalk_reference_hz": 10_000.0,
}
SCATTER = {"mounting_offset_mm": 1.5, "rocking_scatter": 0.06, "crosstalk_scatter": 0.5}
POSITIONS = [PositionGeometry("A", 0.0), PositionGeometry("B", 0.020, 0.0)]


def _model(**change: float) -> FixtureModel:
    return FixtureModel.from_table({**TABLE, **SCATTER, **change}, POSITIONS)


def test_without_scatter_every_mounting_is_the_table_itself() -> None:
    model = FixtureModel.from_table(TABLE, POSITIONS)
    assert model.scatter is None
    assert model.mounted(7, {"A": 10.0, "B": 10.0}, 120.0) is model


def test_one_dut_moves_the_centre_of_mass_by_its_moment_over_the_total_mass() -> None:
    """One 10 g DUT 1.5 mm off its stud on a 120 g block: e = 10 x 1.5 / 130 mm, whatever
    azimuth the thread stopped at; the azimuth differs from seed to seed."""
    model = _model(rocking_scatter=0.0, crosstalk_scatter=0.0)
    azimuths = set()
    for seed in range(1, 6):
        mount = model.mounted(seed, {"B": 10.0}, 120.0)
        assert mount.eccentricity_m == pytest.approx(10.0 * 1.5e-3 / 130.0, rel=1e-12)
        assert mount.rocking_x == model.rocking_x  # no stiffness scatter stated
        assert mount.scatter is None
        azimuths.add(round(mount.eccentricity_azimuth_deg, 6))
    assert len(azimuths) == 5


def test_a_seed_gives_the_same_mounting_and_another_seed_another() -> None:
    model = _model()
    masses = {"A": 10.0, "B": 10.0}
    one, again, other = (model.mounted(s, masses, 120.0) for s in (3, 3, 4))
    assert one == again
    assert one.eccentricity_m != other.eccentricity_m
    # both rocking frequencies by the one contact's stiffness: their ratio is the table's
    assert one.rocking_x.frequency_hz != model.rocking_x.frequency_hz
    assert one.rocking_y.frequency_hz / one.rocking_x.frequency_hz == pytest.approx(12.8 / 11.2)
    assert one.crosstalk_db != model.crosstalk_db


def test_an_unknown_position_and_a_bad_scatter_are_refused_by_name() -> None:
    with pytest.raises(InputRefused, match="'Z'"):
        _model().mounted(1, {"Z": 10.0}, 120.0)
    with pytest.raises(InputRefused, match="rocking_scatter"):
        _model(rocking_scatter=-0.1)


def test_the_lab_states_the_rms_over_its_mountings() -> None:
    """One DUT at B, offset e = m o / M at a uniform azimuth: well below the modes the relative
    motion at B is d e cos(phi_e) (f / f0)^2 / rho^2, so its rms over the azimuths is that
    amplitude over sqrt 2 (the lab's 2000 mountings: within 4 %)."""
    model = _model(rocking_scatter=0.0, crosstalk_scatter=0.0)
    f = 5000.0
    terms, _ = characterised_terms(model, {"B": 10.0}, 120.0, [100.0, f], mountings=2000)
    term = {t.position: t for t in terms}["B"]
    e = 10.0 * 1.5e-3 / 130.0
    h = abs(f**2 / (12_800.0**2 - f**2 + 1j * f * 12_800.0 / 25.0))
    expected = 100.0 * 0.020 * e * h / 0.030**2 / math.sqrt(2.0)
    assert dict(term.magnitude)[f] == pytest.approx(expected, rel=0.04)
    assert dict({t.position: t for t in terms}["A"].magnitude)[f] == 0.005  # the floor


def test_the_lab_margin_scales_the_stated_terms_and_the_crosstalk_is_its_rms() -> None:
    model = _model()
    masses = {"A": 10.0, "B": 10.0}
    one, db = characterised_terms(model, masses, 120.0, [5000.0, 10_000.0])
    two, _ = characterised_terms(model, masses, 120.0, [5000.0, 10_000.0], margin=2.0)
    ratio = dict(two[1].magnitude)[10_000.0] / dict(one[1].magnitude)[10_000.0]
    assert ratio == pytest.approx(2.0, rel=0.05)  # two digits rounded up
    # -90 dB at 10 kHz of which the capacitive part scatters by exp(0.5 Z): rms exp(0.25)
    assert -90.0 < db <= math.ceil(-90.0 + 20 * math.log10(math.exp(0.25)) + 1.5)


def test_the_simulated_stand_mounts_the_block_per_seed() -> None:
    model = _model()
    duts = {"dut.A": "piezo", "dut.B": "piezo"}
    first = FixtureStand(duts, fixture=model, fixture_mass_g=120.0, seed=5, systematic=False)
    again = FixtureStand(duts, fixture=model, fixture_mass_g=120.0, seed=5, systematic=False)
    other = FixtureStand(duts, fixture=model, fixture_mass_g=120.0, seed=6, systematic=False)
    assert first.fixture == again.fixture
    assert first.fixture != other.fixture
    f = np.array([10_000.0])
    assert first.fixture.motion_ratio("B", f) != other.fixture.motion_ratio("B", f)
