"""The simulated fixture's physics (sim/fixture.py) against answers worked by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hardware.errors import InputRefused
from sim.fixture import (
    FixtureModel,
    PositionGeometry,
    interpolated,
    relative_motion_truth,
    stated_terms,
)

ROCKING_HZ = 8000.0
Q = 25.0
E_MM = 0.5
RHO_MM = 25.0
TABLE = {
    "rocking_hz": ROCKING_HZ,
    "rocking_q": Q,
    "eccentricity_mm": E_MM,
    "eccentricity_azimuth_deg": 0.0,  # the offset along x: rocking about y
    "gyration_radius_mm": RHO_MM,
    "crosstalk_db": -80.0,
    "crosstalk_flat_db": -100.0,
    "crosstalk_reference_hz": 10_000.0,
}
POSITIONS = [
    PositionGeometry("A", 0.0),
    PositionGeometry("B", 0.020, 0.0),
    PositionGeometry("C", 0.020, 180.0),
    PositionGeometry("D", 0.040, 0.0),
    PositionGeometry("E", 0.020, 90.0),  # on the nodal line of the rocking about y
]


@pytest.fixture
def model() -> FixtureModel:
    return FixtureModel.from_table(TABLE, POSITIONS)


def test_on_axis_the_ratio_is_exactly_one(model):
    f = np.array([0.0, 10.0, 1000.0, ROCKING_HZ, 20_000.0])
    assert np.array_equal(model.motion_ratio("A", f), np.ones(5, dtype=complex))


def test_well_below_the_mode_relative_motion_is_d_e_over_rho2_times_f2(model):
    """ratio - 1 = d e / rho^2 (f / f0)^2 by hand at 10 Hz, its imaginary part that times
    -(f / f0) / Q (the damping's lag)."""
    f = np.array([10.0])
    expected = 0.020 * 0.5e-3 / 0.025**2 * (10.0 / ROCKING_HZ) ** 2
    got = model.motion_ratio("B", f) - 1.0
    assert got.real[0] == pytest.approx(expected, rel=1e-6)
    assert got.imag[0] == pytest.approx(-expected * 10.0 / ROCKING_HZ / Q, rel=1e-4)


def test_relative_motion_grows_as_f_squared_and_with_d(model):
    f = np.geomspace(10.0, 200.0, 12)
    near = np.abs(model.motion_ratio("B", f) - 1.0)
    far = np.abs(model.motion_ratio("D", f) - 1.0)
    slope = np.polyfit(np.log(f), np.log(near), 1)[0]
    assert slope == pytest.approx(2.0, rel=0.02)
    np.testing.assert_allclose(far / near, 2.0, rtol=1e-7)  # 40 mm against 20 mm (1 + x - 1)


def test_at_the_rocking_mode_the_relative_motion_peaks_at_q(model):
    """At f0, H = -jQ: |ratio - 1| = d e Q / rho^2, the largest over frequency."""
    f = np.linspace(0.8 * ROCKING_HZ, 1.2 * ROCKING_HZ, 4001)
    relative = np.abs(model.motion_ratio("B", f) - 1.0)
    at_mode = 0.020 * 0.5e-3 / 0.025**2 * Q
    assert np.abs(model.motion_ratio("B", np.array([ROCKING_HZ])) - 1.0)[0] == pytest.approx(
        at_mode, rel=1e-12
    )
    assert relative.max() == pytest.approx(at_mode, rel=2e-3)  # the peak is Q sqrt(1 + ..)
    assert abs(f[relative.argmax()] - ROCKING_HZ) < 0.01 * ROCKING_HZ


def test_opposite_azimuths_give_opposite_signs(model):
    f = np.array([100.0, 1000.0, ROCKING_HZ, 15_000.0])
    b = model.motion_ratio("B", f) - 1.0
    c = model.motion_ratio("C", f) - 1.0
    np.testing.assert_allclose(c, -b, rtol=1e-12)
    assert np.all(b.real[:2] > 0)  # the eccentric mass's side moves more below the mode


def test_a_position_on_the_nodal_line_sees_no_rocking(model):
    """Azimuth 90 degrees with the eccentricity along x: cos(phi) = 0, only e_y would move it."""
    relative = model.motion_ratio("E", np.array([1000.0, ROCKING_HZ])) - 1.0
    assert np.all(np.abs(relative) < 1e-15)


def test_two_axes_each_excited_by_its_own_eccentricity_component():
    table = dict(TABLE, rocking_hz=[5000.0, 9000.0], eccentricity_azimuth_deg=90.0)
    model = FixtureModel.from_table(table, [PositionGeometry("Y", 0.02, 90.0)])
    f = np.linspace(4000.0, 10_000.0, 3001)
    relative = np.abs(model.motion_ratio("Y", f) - 1.0)
    assert abs(f[relative.argmax()] - 5000.0) < 50.0  # e_y rocks about x, whose mode is 5 kHz


def test_bending_grows_as_d_squared_and_spares_the_axis():
    table = dict(
        TABLE,
        eccentricity_mm=0.0,
        bending_hz=20_000.0,
        bending_q=30.0,
        bending_participation=0.02,
        block_radius_mm=40.0,
    )
    model = FixtureModel.from_table(table, POSITIONS)
    f = np.array([500.0])
    near = model.motion_ratio("B", f) - 1.0
    r2 = (500.0 / 20_000.0) ** 2
    expected = 0.02 * (20.0 / 40.0) ** 2 * r2 / (1 - r2)  # damping: (r / Q)^2 = 7e-7 of it
    assert near.real[0] == pytest.approx(expected, rel=1e-5)
    far = model.motion_ratio("D", f) - 1.0
    assert far.real[0] / near.real[0] == pytest.approx(4.0, rel=1e-8)  # (1 + x - 1)
    assert model.motion_ratio("A", f)[0] == 1.0


def test_crosstalk_is_one_on_the_diagonal_and_the_stated_db_at_its_frequency(model):
    channels = ["reference", "dut.A", "dut.B"]
    c = model.crosstalk(np.array([10.0, 10_000.0]), channels)
    assert c.shape == (2, 3, 3)
    assert np.all(c[:, [0, 1, 2], [0, 1, 2]] == 1.0)
    off = ~np.eye(3, dtype=bool)
    db_at_reference = 20 * np.log10(np.abs(c[1][off]))
    np.testing.assert_allclose(db_at_reference, -80.0, atol=1e-9)
    # at 10 Hz the capacitive part is 1/1000 of its size: the flat -100 dB is left, nearly
    assert 20 * math.log10(abs(c[0, 0, 1])) == pytest.approx(-100.0, abs=0.01)


def test_crosstalk_grows_with_frequency():
    table = dict(TABLE, crosstalk_flat_db=-140.0)
    model = FixtureModel.from_table(table, POSITIONS)
    c = model.crosstalk(np.array([1000.0, 10_000.0]), ["reference", "dut"])
    assert abs(c[1, 0, 1]) / abs(c[0, 0, 1]) == pytest.approx(10.0, rel=1e-3)  # 20 dB/decade


@pytest.mark.parametrize(
    ("change", "named"),
    [
        ({"rocking_hzz": 1.0}, "rocking_hzz"),
        ({"rocking_q": "high"}, "rocking_q"),
        ({"rocking_hz": [1.0, 2.0, 3.0]}, "rocking_hz"),
        ({"eccentricity_mm": -1.0}, "eccentricity_mm"),
        ({"crosstalk_flat_db": -70.0}, "crosstalk_flat_db"),
        ({"bending_q": 10.0}, "bending_q"),
        ({"gyration_radius_mm": float("nan")}, "gyration_radius_mm"),
    ],
)
def test_from_table_refuses_a_bad_key_naming_it(change, named):
    with pytest.raises(InputRefused, match=rf"\[simulation\.fixture\] {named}:"):
        FixtureModel.from_table(dict(TABLE, **change), POSITIONS)


def test_from_table_refuses_a_missing_key_naming_it():
    table = {k: v for k, v in TABLE.items() if k != "crosstalk_db"}
    with pytest.raises(InputRefused, match=r"crosstalk_db: missing"):
        FixtureModel.from_table(table, POSITIONS)


def test_an_unknown_position_and_a_doubled_one_are_refused_by_name(model):
    with pytest.raises(InputRefused, match="'Z': unknown"):
        model.motion_ratio("Z", np.array([10.0]))
    with pytest.raises(InputRefused, match="'B': named twice"):
        FixtureModel.from_table(TABLE, [*POSITIONS, PositionGeometry("B", 0.01)])


def test_the_stated_terms_bound_the_truth_between_their_nodes(model):
    """The stated rows, log-log interpolated, stay above the truth at every frequency between
    the first and last node, the rocking peak included (the non-circular check's premise)."""
    nodes = [10.0, 100.0, 1000.0, 4000.0, 8000.0, 10_000.0]
    terms = {t.position: t for t in stated_terms(model, nodes, margin=1.2)}
    f = np.geomspace(10.0, 10_000.0, 2000)
    truth = relative_motion_truth(model, f)
    for name, (magnitude, phase) in truth.items():
        assert np.all(interpolated(terms[name].magnitude, f) >= 1.2 * magnitude * (1 - 1e-9))
        assert np.all(interpolated(terms[name].phase, f) >= np.abs(phase))
    assert terms["A"].magnitude[0][1] == 0.005  # on the axis only the floor
    # where nothing bends the curve the row is the margin times the truth, rounded up
    at_1k = dict(terms["D"].magnitude)[1000.0]
    truth_1k = relative_motion_truth(model, [1000.0])["D"][0][0]
    assert 1.2 * truth_1k <= at_1k <= 1.21 * truth_1k
    # the rocking mode is a row of its own
    assert ROCKING_HZ in dict(terms["D"].magnitude)


def test_from_stand_reads_the_positions_geometry_and_the_physics():
    stand = {
        "fixture": {
            "position": [
                {"name": "A", "physical": "sim/ai1"},
                {"name": "B", "distance_mm": 20.0, "azimuth_deg": 180.0},
            ]
        },
        "simulation": {"fixture": TABLE},
    }
    model = FixtureModel.from_stand(stand)
    assert model is not None
    assert model.positions["B"] == PositionGeometry("B", 0.020, 180.0)
    assert model.positions["A"] == PositionGeometry("A", 0.0, 0.0)
    assert FixtureModel.from_stand({"fixture": stand["fixture"]}) is None  # rigid
    stand["fixture"]["position"][1]["distance_mm"] = "far"
    with pytest.raises(InputRefused, match=r"\[\[fixture.position\]\] 2 distance_mm: 'far'"):
        FixtureModel.from_stand(stand)


def test_a_repeated_grid_gives_the_same_ratio_and_a_caller_cannot_spoil_it(model):
    """The stand asks for the same bins every period: kept, handed out as a copy."""
    f = np.fft.rfftfreq(64, 1 / 20_000.0)
    first = model.motion_ratio("B", f)
    first[:] = 0.0
    again = model.motion_ratio("B", f)
    np.testing.assert_array_equal(
        again, FixtureModel.from_table(TABLE, POSITIONS).motion_ratio("B", f)
    )
    assert np.all(again != 0.0)
    assert model.motion_ratio("D", f)[5] != again[5]  # the position is part of the key
    assert model.motion_ratio("B", f[:10]).shape == (10,)  # and the grid
