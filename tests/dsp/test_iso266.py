import pytest

from dsp import iso266


def test_preferred_values_and_exact_frequencies():
    values = iso266.nominal_frequencies(10, 4000)
    assert values[:8] == (10.0, 12.5, 16.0, 20.0, 25.0, 31.5, 40.0, 50.0)
    assert values[-3:] == (2500.0, 3150.0, 4000.0)
    assert len(iso266.nominal_frequencies(10, 2500)) == 25
    assert len(iso266.nominal_frequencies()) == 44  # 1 Hz .. 20 kHz
    assert iso266.exact_frequency(iso266.band_number(1000.0)) == pytest.approx(1000.0)
    assert iso266.exact_frequency(iso266.band_number(31.5)) == pytest.approx(31.6228, rel=1e-5)
    assert iso266.nominal_frequency(43) == 20000.0


@pytest.mark.parametrize("bad", [11.0, 0.0, -10.0, 30000.0, float("nan")])
def test_non_preferred_values_are_refused(bad):
    with pytest.raises(ValueError, match="ISO 266"):
        iso266.band_number(bad)
    assert not iso266.is_preferred(bad)
